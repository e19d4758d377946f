#include "gateways/command_service.hpp"

#include <spdlog/spdlog.h>

#include <stdexcept>

#include "dds/service.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

namespace srv = linebridge_msgs::srv;

std::vector<CommandBit> resolve_commands(const profiles::BitSet& control_word, const std::vector<std::string>& names) {
  std::vector<CommandBit> out;
  for (const auto& n : names) {
    if (auto bit = control_word.bit(n)) out.push_back({n, *bit});
  }
  return out;
}

void serve_commands(const DeviceContext& ctx, std::vector<CommandBit> commands, MomentaryCommands& pulses) {
  using Service = ddsl::ServiceServer<srv::Command_RequestPubSubType, srv::Command_ResponsePubSubType>;
  auto served = Service::serve(
      ctx.dds, ctx.line + "/" + ctx.device.name + "/command",
      [ctx, commands = std::move(commands), &pulses](const srv::Command_Request& req, Service::Responder respond) {
        const auto reply = [respond](bool ok, std::string message) {
          srv::Command_Response r;
          r.success(ok);
          r.message(std::move(message));
          respond(r);
        };
        const CommandBit* cmd = nullptr;
        std::string known;
        for (const auto& c : commands) {
          if (c.name == req.command()) cmd = &c;
          known += (known.empty() ? "" : ", ") + c.name;
        }
        if (cmd == nullptr) return reply(false, "unknown command '" + req.command() + "' (" + known + ")");
        if (!ctx.is_master()) {
          return reply(false, "bus " + ctx.bus.name + " is in the monitor role: the bridge never transmits there");
        }
        ctx.loop.post([ctx, bit = cmd->bit, name = cmd->name, &pulses, reply] {
          if (!ctx.node.online()) return reply(false, ctx.device.name + " is offline (no heartbeat): command not sent");
          pulses.pulse(bit);
          spdlog::info("{}: command {} (control word bit {}) held for 100 ms", ctx.device.name, name, bit);
          reply(true, "");
        });
      });
  if (!served) throw std::runtime_error(ctx.device.name + ": " + served.error().message);
}

}  // namespace lb::gateways
