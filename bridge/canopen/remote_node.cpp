#include "canopen/remote_node.hpp"

#include <spdlog/spdlog.h>

namespace lb::canopen {

RemoteNode::RemoteNode(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_timeout,
                       bool may_transmit)
    : loop_(loop),
      may_transmit_(may_transmit),
      heartbeat_(loop, node_id, heartbeat_timeout,
                 HeartbeatConsumer::Listener{
                     .on_boot_up = [this] { booted(); },
                     .on_change = [this](NmtState s, bool o) { changed(s, o); },
                 }) {
  loop_.on_frame(cob::emcy_base + node_id, [this](const can::CanFrame& f) { on_emcy_frame(f); });
}

void RemoteNode::start() {
  if (!may_transmit_) return;
  if (boot_handler_) {
    boot_handler_();
  } else {
    (void)command(NmtCommand::start);
  }
}

Result<void> RemoteNode::command(NmtCommand cmd) {
  if (!may_transmit_) return make_error("the bus is in the monitor role: the bridge sends no NMT commands there");
  if (auto r = loop_.send(make_nmt_command(cmd, node_id())); !r) return r;
  // Only a start makes the node ours to send RPDOs to; any other command hands it back.
  started_ = cmd == NmtCommand::start;
  return {};
}

void RemoteNode::booted() {
  ++stats_.boot_ups;
  started_ = false;
  spdlog::info("{}: node {} booted (boot-up #{})", loop_.bus().uri(), node_id(), stats_.boot_ups);
  start();
}

void RemoteNode::changed(NmtState state, bool online) {
  // A device we started that reports pre-operational missed the start or was switched back by
  // someone else: start it again, once per state change.
  if (may_transmit_ && started_ && online && state == NmtState::pre_operational) (void)command(NmtCommand::start);
  for (const auto& l : listeners_) l(state, online);
}

void RemoteNode::on_emcy_frame(const can::CanFrame& frame) {
  const auto e = parse_emergency(frame);
  if (!e) {
    spdlog::warn("{}: node {}: EMCY with {} bytes ignored (CiA 301: 8)", loop_.bus().uri(), node_id(), frame.len);
    return;
  }
  ++stats_.emergencies;
  errors_.apply(*e);
  spdlog::log(e->is_reset() ? spdlog::level::info : spdlog::level::warn, "{}: node {} EMCY {:04X}h ({}), register {:02X}h",
              loop_.bus().uri(), node_id(), e->error_code, emcy_family(e->error_code), e->error_register);
  for (const auto& l : emcy_listeners_) l(*e);
}

}  // namespace lb::canopen
