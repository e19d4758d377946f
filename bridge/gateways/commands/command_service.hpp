#pragma once
// A device's momentary commands by name (the work behind the line-wide `command` service, which
// ManagementServices serves once per bridge and hands to the named device's CommandService).
// Validated on the DDS thread (known command, master role), pressed on the loop thread (device
// online).

#include <functional>
#include <string>
#include <vector>

#include "dds/service.hpp"
#include "gateways/commands/momentary_commands.hpp"
#include "gateways/node/device_context.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

struct CommandBit {
  std::string name;  // the profile's bit name, e.g. "manual_cut"
  unsigned bit;
  bool stopping = false;  // marked `stopping` in the profile: never refused while the device is heard
};

// Resolves the names in the profile's bit set; names the profile lacks (older versions) are left
// out.
std::vector<CommandBit> resolve_commands(const profiles::BitSet& control_word, const std::vector<std::string>& names);

class CommandService {
 public:
  // Loop thread: for a stopping command on a device the bridge has not started (boot under way or
  // failed, state unknown): true when it is heard running and its RPDOs may carry the pulse, after
  // every enabling level was switched off in the image (PdoWiring::takes_a_safe_image).
  using StopAnyway = std::function<bool()>;
  // pulses belongs to the device's gateway, which owns this service too.
  CommandService(const DeviceContext& ctx, std::vector<CommandBit> commands, MomentaryCommands& pulses,
                 StopAnyway stop_anyway = {})
      : ctx_(ctx), commands_(std::move(commands)), pulses_(pulses), stop_anyway_(std::move(stop_anyway)) {}
  CommandService(const CommandService&) = delete;
  CommandService& operator=(const CommandService&) = delete;

  // Any thread (a Fast DDS thread); answers at once when refused, else from the loop thread.
  void handle(const linebridge_msgs::srv::Command_Request& request,
              const ddsl::Respond<linebridge_msgs::srv::Command_Response>& respond) const;
  const std::vector<CommandBit>& commands() const { return commands_; }

 private:
  DeviceContext ctx_;
  std::vector<CommandBit> commands_;  // immutable: read from any thread
  MomentaryCommands& pulses_;         // loop thread
  StopAnyway stop_anyway_;            // loop thread
};

}  // namespace lb::gateways
