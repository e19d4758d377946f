// The one body of the profile frame tests: a frame written by hand from the specification, decoded
// (and, for a receive PDO, encoded again) by the production PDO codec. Each test_profile_*.cpp
// links this file and instantiates ProfileFrame with its own table of frames.
#include <gtest/gtest.h>

#include <span>
#include <string_view>

#include "support/profile_spec.hpp"

namespace lb::test::spec {

TEST_P(ProfileFrame, DecodesAsTheSpecificationSays) {
  const auto& [profile, version, f] = GetParam();
  const auto registry = profiles::ProfileRegistry::builtin();
  const auto* p = registry.find(profile, version);
  ASSERT_NE(p, nullptr) << profile << " " << version;
  const auto* pdo = p->pdo(f.pdo);
  ASSERT_NE(pdo, nullptr) << f.pdo;
  const std::span<const std::uint8_t> bytes(f.bytes);

  Image img(*p, f.pdo);
  if (f.refused) {
    EXPECT_FALSE(img.unpack(bytes));
    return;
  }
  ASSERT_TRUE(img.unpack(bytes));
  for (const auto& v : f.values) {
    const auto* o = p->object(v.index, v.sub);
    ASSERT_NE(o, nullptr) << std::hex << v.index << " sub " << int{v.sub};
    EXPECT_EQ(img.raw(v.index, v.sub), v.raw) << o->name;
    if (v.engineering) {
      EXPECT_DOUBLE_EQ(o->to_engineering(img.raw(v.index, v.sub)), *v.engineering) << o->name;
    }
    if (v.code == nullptr) continue;
    if (std::string_view(v.code) == kInvalidCode) {
      EXPECT_FALSE(o->values.valid(img.raw(v.index, v.sub))) << o->name;
    } else {
      EXPECT_EQ(o->values.name(img.raw(v.index, v.sub)), v.code) << o->name;
    }
  }
  for (const auto& flag : f.flags) {
    const auto* set = p->bitset(flag.bitset);
    ASSERT_NE(set, nullptr) << flag.bitset;
    const auto* field = set->field(flag.field);
    ASSERT_NE(field, nullptr) << flag.bitset << "." << flag.field;
    EXPECT_EQ(field->extract(img.raw(set->index)), flag.value) << flag.bitset << "." << flag.field;
  }
  ASSERT_TRUE(pdo->manufacturer_data || !f.manufacturer) << f.pdo << " carries no manufacturer-specific object";
  if (pdo->manufacturer_data) {
    EXPECT_EQ(pdo->manufacturer_value(bytes), f.manufacturer);
  }

  if (pdo->direction != PdoDirection::rx) return;
  // As the sender: every mapped object set (from its engineering value where there is one) packs
  // to the same bytes, the manufacturer-specific tail aside.
  ASSERT_EQ(f.values.size(), pdo->mapping.size()) << "a receive PDO's frame names every mapped object";
  Image out(*p, f.pdo);
  for (const auto& v : f.values) {
    auto raw = v.raw;
    if (v.engineering) {
      const auto converted = p->object(v.index, v.sub)->to_raw(*v.engineering);
      ASSERT_TRUE(converted) << std::hex << v.index;
      raw = *converted;
    }
    out.set(v.index, v.sub, raw);
  }
  const std::size_t tail = f.manufacturer ? pdo->manufacturer_data->bits / 8 : 0;
  ASSERT_LE(tail, f.bytes.size());
  EXPECT_EQ(out.pack(), std::vector<std::uint8_t>(f.bytes.begin(), f.bytes.end() - static_cast<std::ptrdiff_t>(tail)));
}

}  // namespace lb::test::spec
