#pragma once
// A device's momentary commands by name (the work behind the line-wide `command` service, which
// ManagementServices serves once per bridge and hands to the named device's CommandService).
// Validated on the DDS thread (known command, master role), pressed on the loop thread (device
// online).

#include <string>
#include <vector>

#include "dds/service.hpp"
#include "gateways/device_context.hpp"
#include "gateways/momentary_commands.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

struct CommandBit {
  std::string name;  // the profile's bit name, e.g. "manual_cut"
  unsigned bit;
};

// Resolves the names in the profile's bit set; names the profile lacks (older versions) are left
// out.
std::vector<CommandBit> resolve_commands(const profiles::BitSet& control_word, const std::vector<std::string>& names);

class CommandService {
 public:
  // pulses belongs to the device's gateway, which owns this service too.
  CommandService(const DeviceContext& ctx, std::vector<CommandBit> commands, MomentaryCommands& pulses)
      : ctx_(ctx), commands_(std::move(commands)), pulses_(pulses) {}
  CommandService(const CommandService&) = delete;
  CommandService& operator=(const CommandService&) = delete;

  // Any thread (a Fast DDS thread); answers at once when refused, else from the loop thread.
  void handle(const linebridge_msgs::srv::Command_Request& request,
              ddsl::Respond<linebridge_msgs::srv::Command_Response> respond) const;
  const std::vector<CommandBit>& commands() const { return commands_; }

 private:
  DeviceContext ctx_;
  std::vector<CommandBit> commands_;  // immutable: read from any thread
  MomentaryCommands& pulses_;         // loop thread
};

}  // namespace lb::gateways
