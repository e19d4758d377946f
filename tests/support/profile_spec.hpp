#pragma once
// The shapes of the tables a profile specification prints (objects, default PDOs, frames), so that
// each profile test holds its hand-written vectors as data and every profile is checked by the same
// code. The expected values stay in the test files, typed in from the specification: nothing here
// derives an expectation from the code under test.

#include <gtest/gtest.h>

#include <cstdint>
#include <optional>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "canopen/pdo_mapping.hpp"
#include "profiles/profile_registry.hpp"
#include "support/profile_image.hpp"

namespace lb::test::spec {

// The vocabulary of the tables, for `using namespace lb::test::spec;` in a profile test.
using canopen::DataType;
using canopen::PdoEntry;
using profiles::Access;
using profiles::PdoDirection;
using profiles::PdoValidity;
using profiles::Profile;
using test::Bits;
using test::entries;
using test::expect_bits;
using test::Image;

inline const std::optional<std::int64_t> none;

// One row of an object table: a VAR, or what every element of an ARRAY shares.
struct Variable {
  std::uint16_t index;
  const char* name;
  DataType type;
  Access access;
  const char* unit;
  double scale;
  const char* eng_unit;
  std::optional<std::int64_t> min, max;
};

inline void expect_object(const profiles::ObjectDef& o, const Variable& e, const std::string& name) {
  EXPECT_EQ(o.name, name);
  EXPECT_EQ(o.type, e.type) << name;
  EXPECT_EQ(o.access, e.access) << name;
  EXPECT_EQ(o.unit, e.unit) << name;
  EXPECT_DOUBLE_EQ(o.scale, e.scale) << name;
  EXPECT_EQ(o.eng_unit, e.eng_unit) << name;
  EXPECT_EQ(o.min, e.min) << name;
  EXPECT_EQ(o.max, e.max) << name;
}

// Every row is a mandatory VAR (no sub-index 1).
inline void expect_variables(const Profile& p, const std::vector<Variable>& rows) {
  for (const auto& e : rows) {
    const auto* o = p.object(e.index);
    ASSERT_NE(o, nullptr) << std::hex << e.index;
    expect_object(*o, e, e.name);
    EXPECT_TRUE(o->mandatory) << e.name;
    EXPECT_EQ(p.object(e.index, 1), nullptr) << e.name << ": VAR, not ARRAY";
  }
}

// Every row is an optional ARRAY: sub 0 a const UNSIGNED8 count, subs 1..elements named
// "<name>_<sub>" and alike, nothing after them.
inline void expect_arrays(const Profile& p, const std::vector<Variable>& rows, std::uint8_t elements) {
  for (const auto& e : rows) {
    const auto* count = p.object(e.index, 0);
    ASSERT_NE(count, nullptr) << e.name;
    EXPECT_EQ(count->type, DataType::unsigned8);
    EXPECT_EQ(count->access, Access::const_);
    EXPECT_FALSE(count->mandatory);
    for (std::uint8_t sub = 1; sub <= elements; ++sub) {
      const auto* o = p.object(e.index, sub);
      ASSERT_NE(o, nullptr) << e.name << " sub " << int{sub};
      expect_object(*o, e, std::string(e.name) + "_" + std::to_string(sub));
      EXPECT_FALSE(o->mandatory) << o->name;
    }
    EXPECT_EQ(p.object(e.index, static_cast<std::uint8_t>(elements + 1)), nullptr) << e.name;
  }
}

// The manufacturer-specific object a PDO may carry after its mapped ones.
struct Tail {
  const char* name;
  unsigned bits;
};

// One row of the default PDO tables; cob_id is the one for the node-ID the check is given.
struct DefaultPdo {
  const char* name;
  PdoDirection direction;
  std::uint32_t cob_id;
  int transmission_type;
  PdoValidity validity;
  bool mandatory;
  std::vector<PdoEntry> mapping;
  std::optional<Tail> manufacturer_data = std::nullopt;
};

// Exactly these PDOs.
inline void expect_pdos(const Profile& p, std::uint8_t node_id, const std::vector<DefaultPdo>& rows) {
  EXPECT_EQ(p.pdos.size(), rows.size());
  for (const auto& e : rows) {
    const auto* pdo = p.pdo(e.name);
    ASSERT_NE(pdo, nullptr) << e.name;
    EXPECT_EQ(pdo->direction, e.direction) << e.name;
    EXPECT_EQ(pdo->cob_id(node_id), e.cob_id) << e.name;
    EXPECT_EQ(pdo->transmission_type, e.transmission_type) << e.name;
    EXPECT_EQ(pdo->validity, e.validity) << e.name;
    EXPECT_EQ(pdo->mandatory, e.mandatory) << e.name;
    EXPECT_EQ(pdo->mapping, e.mapping) << e.name;
    ASSERT_EQ(pdo->manufacturer_data.has_value(), e.manufacturer_data.has_value()) << e.name;
    if (e.manufacturer_data) {
      EXPECT_EQ(pdo->manufacturer_data->name, e.manufacturer_data->name) << e.name;
      EXPECT_EQ(pdo->manufacturer_data->bits, e.manufacturer_data->bits) << e.name;
    }
  }
}

// A code of a value table that must be refused (reserved, or in no row).
inline constexpr const char* kInvalidCode = "<invalid>";

// One mapped object of a frame: its raw value and, where the specification gives them, its
// engineering value and the name of its code.
struct Value {
  std::uint16_t index;
  std::uint8_t sub;
  std::uint64_t raw;
  std::optional<double> engineering = std::nullopt;
  const char* code = nullptr;  // kInvalidCode: valid() must say no
};

// One named field of a bit set, as read from the raw value of the bit set's object.
struct Flag {
  const char* bitset;
  const char* field;
  std::uint64_t value;
};

// A frame written by hand and what the bridge must read from it. A receive PDO must also come out
// of the bridge as the same bytes when it sends these values (engineering ones converted back).
struct Frame {
  const char* name;  // the test's name
  const char* pdo;
  std::vector<std::uint8_t> bytes;
  std::vector<Value> values;
  std::vector<Flag> flags = {};
  std::optional<std::uint64_t> manufacturer = std::nullopt;  // checked where the PDO may carry one
  bool refused = false;                                      // too short: the codec must refuse it
};

struct FrameCase {
  const char* profile;
  const char* version;
  Frame frame;
};

// The one test body every profile test instantiates with its table (support/profile_frames.cpp):
// INSTANTIATE_TEST_SUITE_P(Puller, ProfileFrame, ::testing::ValuesIn(frames), frame_name).
class ProfileFrame : public ::testing::TestWithParam<FrameCase> {};

// Names a failing case in gtest's output instead of dumping its bytes.
inline void PrintTo(const FrameCase& c, std::ostream* os) {
  *os << c.profile << " " << c.version << " " << c.frame.name;
}

inline std::string frame_name(const ::testing::TestParamInfo<FrameCase>& info) { return info.param.frame.name; }

inline std::vector<FrameCase> frames_of(const char* profile, const char* version, std::vector<Frame> frames) {
  std::vector<FrameCase> out;
  for (auto& f : frames) out.push_back({profile, version, std::move(f)});
  return out;
}

}  // namespace lb::test::spec
