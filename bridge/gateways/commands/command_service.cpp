#include "gateways/commands/command_service.hpp"

#include <spdlog/spdlog.h>

namespace lb::gateways {

namespace srv = linebridge_msgs::srv;

void CommandService::handle(const srv::Command_Request& req,
                            const ddsl::Respond<srv::Command_Response>& respond) const {
  const auto refuse = [respond](const std::string& message) {
    srv::Command_Response r;
    r.success(false);
    r.message(message);
    respond(r);
  };
  const CommandBit* cmd = nullptr;
  std::string known;
  for (const auto& c : commands_) {
    if (c.name == req.command()) cmd = &c;
    known += (known.empty() ? "" : ", ") + c.name;
  }
  if (cmd == nullptr) return refuse(ctx_.device.name + ": unknown command '" + req.command() + "' (" + known + ")");
  if (!ctx_.is_master()) {
    return refuse("bus " + ctx_.bus.name + " is in the monitor role: the bridge never transmits there");
  }
  const bool posted = ctx_.loop.try_post([this, c = *cmd, refuse, respond] {
    press_(c, refuse,
           [device = ctx_.device.name, name = c.name, bit = c.bit, respond](const MomentaryCommands::Outcome& o) {
             srv::Command_Response r;
             r.success(o.on_bus);
             r.frames(o.frames);
             r.held_ms(std::chrono::duration<double, std::milli>(o.held).count());
             r.message(o.message);
             if (o.on_bus) {
               spdlog::info(
                   "{}: command {} (control word bit {}) on the bus in {} RPDO(s) over {:.1f} ms, then released{}{}",
                   device, name, bit, o.frames, r.held_ms(), o.message.empty() ? "" : "; ", o.message);
             } else {
               spdlog::warn("{}: command {} (control word bit {}) not held on the bus: {}", device, name, bit,
                            o.message);
             }
             respond(r);
           });
  });
  if (!posted) refuse(ctx_.loop_busy(req.command()));
}

}  // namespace lb::gateways
