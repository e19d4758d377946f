#pragma once
// For the profile tests: a PDO of a profile on the bridge's own path (mapping -> binding -> process
// image), so that frames written by hand from the specification are decoded and packed by the
// production code, and checks of a profile's named bits.

#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <initializer_list>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "canopen/pdo_mapping.hpp"
#include "canopen/process_image.hpp"
#include "profiles/profile_registry.hpp"

namespace lb::test {

struct Image {
  canopen::ProcessImage image;
  std::optional<canopen::PdoBinding> binding;

  Image(const profiles::Profile& p, const std::string& pdo_name) {
    const auto* pdo = p.pdo(pdo_name);
    EXPECT_NE(pdo, nullptr) << pdo_name;
    if (pdo == nullptr) return;
    for (const auto& e : pdo->mapping) image.slot(e.index, e.sub);
    auto mapping = canopen::PdoMapping::create(pdo->mapping);
    EXPECT_TRUE(mapping);
    if (mapping) binding.emplace(std::move(*mapping), image);
  }
  bool unpack(std::span<const std::uint8_t> frame) { return binding && binding->unpack_into(frame, image).has_value(); }
  std::uint64_t raw(std::uint16_t index, std::uint8_t sub = 0) const { return image.get(image.find(index, sub)); }
  void set(std::uint16_t index, std::uint64_t raw) { set(index, 0, raw); }
  void set(std::uint16_t index, std::uint8_t sub, std::uint64_t raw) { image.set(image.find(index, sub), raw); }
  std::vector<std::uint8_t> pack() const {
    std::array<std::uint8_t, 8> out{};
    const auto n = binding->pack_from(image, out);
    return {out.begin(), out.begin() + n};
  }
};

// A PDO's mapping from the 32-bit entries a specification table prints.
inline std::vector<canopen::PdoEntry> entries(std::initializer_list<std::uint32_t> values) {
  std::vector<canopen::PdoEntry> out;
  for (auto v : values) out.push_back(canopen::PdoEntry::from_u32(v));
  return out;
}

using Bits = std::vector<std::pair<const char*, unsigned>>;

// Every named flag at its position, and no flag beyond these.
inline void expect_bits(const profiles::Profile& p, const char* set_name, const Bits& bits) {
  const auto* set = p.bitset(set_name);
  ASSERT_NE(set, nullptr) << set_name;
  EXPECT_EQ(set->bits.size(), bits.size()) << set_name;
  for (const auto& [name, bit] : bits) EXPECT_EQ(set->bit(name), bit) << set_name << "." << name;
}

}  // namespace lb::test
