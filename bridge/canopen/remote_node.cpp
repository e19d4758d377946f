#include "canopen/remote_node.hpp"

#include <spdlog/spdlog.h>

namespace lb::canopen {

RemoteNode::RemoteNode(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_timeout,
                       bool may_transmit)
    : loop_(loop),
      may_transmit_(may_transmit),
      heartbeat_(loop, node_id, heartbeat_timeout,
                 HeartbeatConsumer::Listener{
                     .on_boot_up =
                         [this] {
                           spdlog::info("{}: node {} booted", loop_.bus().uri(), this->node_id());
                           started_ = false;
                           if (may_transmit_) send_start();
                         },
                     .on_change = [this](NmtState s, bool o) { changed(s, o); },
                 }) {}

void RemoteNode::start() {
  if (may_transmit_) send_start();
}

void RemoteNode::send_start() {
  if (loop_.send(make_nmt_command(NmtCommand::start, node_id()))) started_ = true;
}

void RemoteNode::changed(NmtState state, bool online) {
  // A device that reports pre-operational although we started it missed the command (or was
  // switched back by someone else): start it again, once per state change.
  if (may_transmit_ && online && state == NmtState::pre_operational) send_start();
  for (const auto& l : listeners_) l(state, online);
}

}  // namespace lb::canopen
