#pragma once
// A device's momentary commands by name (the work behind the line-wide `command` service, which
// ManagementServices serves once per bridge and hands to the named device's CommandService).
// Validated on the DDS thread (known command, master role), pressed on the loop thread through the
// device's output (DeviceOutput::press: a stopping command goes out whenever the device is heard).

#include <functional>
#include <string>
#include <vector>

#include "dds/service.hpp"
#include "gateways/node/command_bits.hpp"
#include "gateways/node/device_context.hpp"
#include "gateways/node/momentary_commands.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

class CommandService {
 public:
  // Loop thread: presses a command through the device's output; refuse(reason) at once, or
  // done(outcome) once the pulse is over.
  using Press = std::function<void(const CommandBit& command, const std::function<void(const std::string&)>& refuse,
                                   MomentaryCommands::Done done)>;
  CommandService(const DeviceContext& ctx, std::vector<CommandBit> commands, Press press)
      : ctx_(ctx), commands_(std::move(commands)), press_(std::move(press)) {}
  CommandService(const CommandService&) = delete;
  CommandService& operator=(const CommandService&) = delete;

  // Any thread (a Fast DDS thread); answers at once when refused, else from the loop thread.
  void handle(const linebridge_msgs::srv::Command_Request& request,
              const ddsl::Respond<linebridge_msgs::srv::Command_Response>& respond) const;
  const std::vector<CommandBit>& commands() const { return commands_; }

 private:
  DeviceContext ctx_;
  std::vector<CommandBit> commands_;  // immutable: read from any thread
  Press press_;                       // loop thread
};

}  // namespace lb::gateways
