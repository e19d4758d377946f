#pragma once
// The profile objects, bit sets and bits a codec decodes by. A profile without one cannot be
// served, so its absence ends start-up with the profile and the name.

#include <stdexcept>
#include <string>
#include <string_view>

#include "profiles/profile.hpp"

namespace lb::gateways {

inline const profiles::ObjectDef& required_object(const profiles::Profile& profile, std::string_view name) {
  const auto* def = profile.object(name);
  if (def == nullptr)
    throw std::runtime_error("profile " + profile.key() + " has no object '" + std::string(name) + "'");
  return *def;
}

inline const profiles::BitSet& required_bitset(const profiles::Profile& profile, std::string_view name) {
  const auto* set = profile.bitset(name);
  if (set == nullptr)
    throw std::runtime_error("profile " + profile.key() + " has no bit set '" + std::string(name) + "'");
  return *set;
}

inline unsigned required_bit(const profiles::Profile& profile, const profiles::BitSet& set, std::string_view name) {
  const auto bit = set.bit(name);
  if (!bit)
    throw std::runtime_error("profile " + profile.key() + ": bit set " + set.name + " has no bit '" +
                             std::string(name) + "'");
  return *bit;
}

}  // namespace lb::gateways
