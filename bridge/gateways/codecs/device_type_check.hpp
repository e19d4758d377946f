#pragma once
// What lb-check-device-types checks, as a function of its inputs, so that a test can hand it a
// broken registry or profile and see each disagreement named:
//   - every profile names a registered type, of the entry's profile id and versions;
//   - every registered type and version has its profile;
//   - a drive type's IDL declares a drive-shaped binding; any type's word binding (drives, saw)
//     and its profiles' status and control word bits are the same names: a bit no field shows
//     would be dropped silently, a field no profile names would never be set.

#include <span>
#include <string>
#include <vector>

#include "profiles/device_types.hpp"
#include "profiles/profile_registry.hpp"

namespace lb::gateways {

// Every disagreement, one sentence each; empty when they agree.
std::vector<std::string> check_device_types(const profiles::ProfileRegistry& registry,
                                            std::span<const profiles::DeviceType> types);

}  // namespace lb::gateways
