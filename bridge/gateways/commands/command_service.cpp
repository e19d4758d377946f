#include "gateways/commands/command_service.hpp"

#include <spdlog/spdlog.h>

#include "gateways/node/set_value_path.hpp"

namespace lb::gateways {

namespace srv = linebridge_msgs::srv;

std::vector<CommandBit> resolve_commands(const profiles::BitSet& control_word, const std::vector<std::string>& names) {
  std::vector<CommandBit> out;
  for (const auto& n : names) {
    if (auto bit = control_word.bit(n)) out.push_back({n, *bit, control_word.field(n)->stopping});
  }
  return out;
}

void CommandService::handle(const srv::Command_Request& req,
                            const ddsl::Respond<srv::Command_Response>& respond) const {
  const auto refuse = [respond](std::string message) {
    srv::Command_Response r;
    r.success(false);
    r.message(std::move(message));
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
  const bool posted = ctx_.loop.try_post([this, bit = cmd->bit, name = cmd->name, stopping = cmd->stopping, refuse,
                                          respond] {
    // Refused at once when no frame could carry it; otherwise answered when the pulse is over.
    if (ctx_.loop.transmission_held()) return refuse(another_master(ctx_, name + " not sent"));
    if (!ctx_.node.online()) return refuse(ctx_.device.name + " is offline (no heartbeat): " + name + " not sent");
    // A stop goes out to a device that is heard running, whatever the bridge knows of its boot.
    if (!ctx_.node.ready_for_pdos() && !(stopping && stop_anyway_ && stop_anyway_())) {
      return refuse(ctx_.device.name +
                    " is not started by this bridge (its boot has not passed, or it was told to "
                    "stop): " +
                    name + " not sent");
    }
    pulses_.press(bit, [device = ctx_.device.name, name, bit, respond](const MomentaryCommands::Outcome& o) {
      srv::Command_Response r;
      r.success(o.on_bus);
      r.frames(o.frames);
      r.held_ms(std::chrono::duration<double, std::milli>(o.held).count());
      r.message(o.message);
      if (o.on_bus) {
        spdlog::info("{}: command {} (control word bit {}) on the bus in {} RPDO(s) over {:.1f} ms, then released{}{}",
                     device, name, bit, o.frames, r.held_ms(), o.message.empty() ? "" : "; ", o.message);
      } else {
        spdlog::warn("{}: command {} (control word bit {}) not held on the bus: {}", device, name, bit, o.message);
      }
      respond(r);
    });
  });
  if (!posted) refuse(ctx_.loop_busy(req.command()));
}

}  // namespace lb::gateways
