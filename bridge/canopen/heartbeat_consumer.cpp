#include "canopen/heartbeat_consumer.hpp"

#include <spdlog/spdlog.h>

namespace lb::canopen {

HeartbeatConsumer::HeartbeatConsumer(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds timeout,
                                     Listener listener)
    : loop_(loop), node_id_(node_id), timeout_(timeout), listener_(std::move(listener)) {
  timer_ = loop_.create_timer([this] { on_timeout(); });
  loop_.on_frame(cob::heartbeat_base + node_id_, [this](const can::CanFrame& f) { on_frame(f); });
}

void HeartbeatConsumer::on_frame(const can::CanFrame& frame) {
  if (frame.len < 1) {
    if (listener_.on_malformed) listener_.on_malformed(frame);
    return;
  }
  last_heartbeat_ns_ = frame.timestamp_ns;
  loop_.arm_timer(timer_, timeout_);
  const NmtState state = nmt_state_from_byte(frame.data[0]);
  const bool changed = state != state_ || !online_;
  if (!online_) spdlog::info("{}: node {} online ({})", loop_.bus().uri(), node_id_, to_string(state));
  state_ = state;
  online_ = true;
  if (state == NmtState::boot_up && listener_.on_boot_up) listener_.on_boot_up();
  if (changed && listener_.on_change) listener_.on_change(state_, online_);
  if (listener_.on_heartbeat) listener_.on_heartbeat(state_);
}

void HeartbeatConsumer::on_timeout() {
  if (!online_) return;
  online_ = false;
  spdlog::warn("{}: node {} lost: no heartbeat for {} ms", loop_.bus().uri(), node_id_, timeout_.count());
  if (listener_.on_change) listener_.on_change(state_, online_);
}

}  // namespace lb::canopen
