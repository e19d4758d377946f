#include "canopen/heartbeat_consumer.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace lb::canopen {

namespace {

std::int64_t realtime_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace

HeartbeatConsumer::HeartbeatConsumer(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds timeout,
                                     Listener listener)
    : loop_(loop), node_id_(node_id), timeout_(timeout), listener_(std::move(listener)) {
  timer_ = loop_.create_timer([this] { on_timeout(); });
  loop_.on_frame(cob::heartbeat_base + node_id_, [this](const can::CanFrame& f) { on_frame(f); });
}

void HeartbeatConsumer::arm(std::chrono::milliseconds after) {
  due_ = std::chrono::steady_clock::now() + after;
  loop_.arm_timer(timer_, after);
}

void HeartbeatConsumer::on_frame(const can::CanFrame& frame) {
  if (frame.len < 1) {
    if (listener_.on_malformed) listener_.on_malformed(frame);
    return;
  }
  last_heartbeat_ns_ = frame.timestamp_ns;
  deadline_ns_ = frame.timestamp_ns + std::chrono::nanoseconds(timeout_).count();
  deferred_since_.reset();
  arm(timeout_);
  const NmtState state = nmt_state_from_byte(frame.data[0]);
  const bool came_online = !online_;
  state_ = state;
  online_ = true;
  if (listener_.on_heartbeat) listener_.on_heartbeat(state, came_online);
}

void HeartbeatConsumer::keep_waiting() {
  if (!online_) return;
  deadline_ns_ = std::max(loop_.last_frame_ns(), realtime_ns()) + std::chrono::nanoseconds(timeout_).count();
  deferred_since_.reset();
  arm(timeout_);
}

void HeartbeatConsumer::on_timeout() {
  if (!online_) return;
  const auto now = std::chrono::steady_clock::now();
  if (!deferred_since_) stalled_ = now - due_ > kLate;
  // Not proven yet on the bus's time: what waits to be read may hold its heartbeat.
  const bool unproven = loop_.last_frame_ns() < deadline_ns_ && (stalled_ || loop_.input_pending());
  const auto bound = stalled_ ? std::min<std::chrono::milliseconds>(timeout_, kJudgementBound) : kJudgementBound;
  if (unproven && (!deferred_since_ || now - *deferred_since_ < bound)) {
    if (!deferred_since_) {
      deferred_since_ = now;
      ++judgements_deferred_;
      spdlog::debug("{}: node {}: heartbeat timer fired{} with frames possibly queued: judged after them",
                    loop_.bus().uri(), node_id_, stalled_ ? " late (the loop was held up)" : "");
    }
    arm(kJudgementRecheck);
    return;
  }
  deferred_since_.reset();
  if (listener_.on_missing && !listener_.on_missing()) return;
  declare_offline();
}

void HeartbeatConsumer::declare_offline() {
  if (!online_) return;
  online_ = false;
  deferred_since_.reset();
  loop_.disarm_timer(timer_);
  if (listener_.on_offline) listener_.on_offline();
}

}  // namespace lb::canopen
