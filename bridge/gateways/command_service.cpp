#include "gateways/command_service.hpp"

#include <spdlog/spdlog.h>

namespace lb::gateways {

namespace srv = linebridge_msgs::srv;

std::vector<CommandBit> resolve_commands(const profiles::BitSet& control_word, const std::vector<std::string>& names) {
  std::vector<CommandBit> out;
  for (const auto& n : names) {
    if (auto bit = control_word.bit(n)) out.push_back({n, *bit});
  }
  return out;
}

void CommandService::handle(const srv::Command_Request& req, ddsl::Respond<srv::Command_Response> respond) const {
  const auto reply = [respond](bool ok, std::string message) {
    srv::Command_Response r;
    r.success(ok);
    r.message(std::move(message));
    respond(r);
  };
  const CommandBit* cmd = nullptr;
  std::string known;
  for (const auto& c : commands_) {
    if (c.name == req.command()) cmd = &c;
    known += (known.empty() ? "" : ", ") + c.name;
  }
  if (cmd == nullptr) return reply(false, ctx_.device.name + ": unknown command '" + req.command() + "' (" + known + ")");
  if (!ctx_.is_master()) {
    return reply(false, "bus " + ctx_.bus.name + " is in the monitor role: the bridge never transmits there");
  }
  ctx_.loop.post([this, bit = cmd->bit, name = cmd->name, reply] {
    if (!ctx_.node.online()) return reply(false, ctx_.device.name + " is offline (no heartbeat): command not sent");
    if (!ctx_.node.ready_for_pdos()) {
      return reply(false, ctx_.device.name + " is not started by this bridge (its boot has not passed, or it was told to "
                                             "stop): command not sent");
    }
    pulses_.pulse(bit);
    spdlog::info("{}: command {} (control word bit {}) held for 100 ms", ctx_.device.name, name, bit);
    reply(true, "");
  });
}

}  // namespace lb::gateways
