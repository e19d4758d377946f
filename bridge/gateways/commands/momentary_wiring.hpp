#pragma once
// A gateway with momentary commands (a drive, the saw) on its node, the same for each: the commands
// count the RPDO frames that carry the control word (momentary_commands.hpp), the gateway is
// attached to its node, and a restarted bridge goes on with the set values in force (a running
// drive keeps its speed, a saw its program) but presses no command that was held at the stop.

#include <string_view>

#include "canopen/node_driver.hpp"
#include "gateways/commands/command_service.hpp"
#include "gateways/commands/momentary_commands.hpp"
#include "gateways/node/device_context.hpp"
#include "gateways/node/pdo_wiring.hpp"

namespace lb::gateways {

template <class Codec>
void attach_with_momentary_commands(const DeviceContext& ctx, canopen::NodeDriver& gateway, PdoWiring<Codec>& pdos,
                                    MomentaryCommands& commands, const CommandService& service, Codec& codec) {
  pdos.observe(ctx.profile.object("control_word")->index,
               {.before_send = [&commands] { commands.before_frame(); },
                .sent = [&commands](auto at) { commands.frame_sent(at); },
                .not_sent = [&commands](std::string_view why) { commands.frame_not_sent(why); }});
  ctx.node.attach(gateway);
  pdos.restore([&service, &codec] {
    for (const auto& c : service.commands()) codec.set_control_bit(c.bit, false);
  });
}

}  // namespace lb::gateways
