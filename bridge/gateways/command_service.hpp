#pragma once
// rq/<line>/<device>/commandRequest: a device's momentary commands by name. Validated on the DDS
// thread (known command, master role), pressed on the loop thread (device online).

#include <string>
#include <vector>

#include "gateways/device_context.hpp"
#include "gateways/momentary_commands.hpp"

namespace lb::gateways {

struct CommandBit {
  std::string name;  // the profile's bit name, e.g. "manual_cut"
  unsigned bit;
};

// Resolves the names in the profile's bit set; names the profile lacks (older versions) are left
// out. Throws std::runtime_error at start-up when the service cannot be created.
std::vector<CommandBit> resolve_commands(const profiles::BitSet& control_word, const std::vector<std::string>& names);
void serve_commands(const DeviceContext& ctx, std::vector<CommandBit> commands, MomentaryCommands& pulses);

}  // namespace lb::gateways
