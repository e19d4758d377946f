#pragma once
// What of a device's set values goes (back) into its RPDOs when the bridge starts it, after every
// boot: the start-up policy (profiles::StartupPolicy) applied to one RPDO payload. Pure logic on
// raw payloads and the profile, so every gateway applies it the same way (DeviceOutput) and the unit
// tests drive it without a bus.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "canopen/pdo_mapping.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile.hpp"

namespace lb::gateways {

enum class RestoreScope {
  all,           // the device kept running: every set value in force
  non_enabling,  // power loss or reset: speeds, lengths, modes; every enabling level off
  nothing,       // power loss or reset, policy after_power_loss: nothing: all zero
};
std::string_view to_string(RestoreScope scope);

// found_operational: the device reported operational before the bridge started it in this boot.
// paused_by_boot: the boot put it in pre-operational to write its PDO parameters; it comes back with
// what enables nothing (a pause is not an operator's decision to run it again).
RestoreScope restore_scope(const profiles::StartupPolicy& policy, bool found_operational, bool starts_itself,
                           bool paused_by_boot = false);

// A kept payload passes the checks a new set value passes: every mapped object of the profile
// within its range (min/max, else its data type) and, for an enumeration, a code it defines;
// every bit field within its printed range. Objects the profile does not know are not checked.
Result<void> check_set_values(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                              std::span<const std::uint8_t> payload);

// Clears every enabling level (bit fields and objects marked `enabling` in the profile) in the
// payload; returns the names of those that were set.
// A payload shorter than the mapping is left as it is.
std::vector<std::string> clear_enabling(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                                        std::span<std::uint8_t> payload);

// Every enabling level the payload carries, in mapping order: its name and raw value (a stop is a
// change that writes 0 to one of them and non-zero to none).
struct EnablingLevel {
  std::string name;
  std::uint64_t value = 0;
};
std::vector<EnablingLevel> enabling_levels(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                                           std::span<const std::uint8_t> payload);
// Sets every enabling level of the payload to all ones (on) or to zero; other bits stay.
void force_enabling(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                    std::span<std::uint8_t> payload, bool on);

}  // namespace lb::gateways
