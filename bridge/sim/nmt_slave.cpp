#include "sim/nmt_slave.hpp"

#include <spdlog/spdlog.h>

namespace lb::sim {

using canopen::NmtCommand;
using canopen::NmtState;

NmtSlave::NmtSlave(canopen::BusLoop& loop, std::uint8_t node_id, Hooks hooks)
    : loop_(loop), node_id_(node_id), hooks_(std::move(hooks)) {
  heartbeat_timer_ = loop_.create_timer([this] { send_heartbeat(); });
  reset_timer_ = loop_.create_timer([this] {
    if (!pending_reset_) return;
    const Reset kind = *pending_reset_;
    pending_reset_.reset();
    reset(kind, announce_nmt_resets_);
  });
  loop_.on_frame(canopen::cob::nmt, [this](const can::CanFrame& f) { on_command(f); });
}

void NmtSlave::reset(Reset kind, bool announce) {
  const NmtState before = state_;
  state_ = NmtState::boot_up;  // initialising: no PDO, and the heartbeat timer is re-armed below
  if (before != NmtState::boot_up && hooks_.state_changed) hooks_.state_changed(before, state_);
  if (hooks_.reset) hooks_.reset(kind);
  if (announce) send_heartbeat();  // the boot-up message is a heartbeat with state 0
  enter(NmtState::pre_operational);
}

void NmtSlave::set_heartbeat_period(std::chrono::milliseconds period) {
  heartbeat_period_ = period;
  if (period.count() == 0) {
    loop_.disarm_timer(heartbeat_timer_);
  } else {
    loop_.arm_timer(heartbeat_timer_, period, period);
  }
}

void NmtSlave::send_heartbeat() { (void)loop_.send(canopen::make_heartbeat(node_id_, state_)); }

void NmtSlave::enter(NmtState state) {
  const NmtState before = state_;
  state_ = state;
  if (before == state) return;
  if (hooks_.state_changed) hooks_.state_changed(before, state);
  // As CANopenNode does: a producer reports a new state at once, not a period later.
  if (heartbeat_period_.count() > 0 && before != NmtState::boot_up) send_heartbeat();
}

// A reset that takes time: initialising at once (what it was running stops, its heartbeat too),
// the power-on values and the boot-up once reset_time_ has passed.
void NmtSlave::begin_reset(Reset kind) {
  if (reset_time_.count() == 0) return reset(kind, announce_nmt_resets_);
  const NmtState before = state_;
  state_ = NmtState::boot_up;
  if (before != NmtState::boot_up && hooks_.state_changed) hooks_.state_changed(before, state_);
  loop_.disarm_timer(heartbeat_timer_);
  pending_reset_ = kind;
  loop_.arm_timer(reset_timer_, reset_time_);
  spdlog::info("sim node {}: reset {}: silent for {} ms (simulation reset_time_ms)", node_id_,
               kind == Reset::node ? "node" : "communication", reset_time_.count());
}

void NmtSlave::communication_error() {
  if (state_ == canopen::NmtState::operational) enter(canopen::NmtState::pre_operational);
}

void NmtSlave::on_command(const can::CanFrame& frame) {
  if (frame.len != 2 || (frame.data[1] != 0 && frame.data[1] != node_id_)) return;
  if (pending_reset_) return;  // initialising: it takes no NMT command until it is back
  switch (static_cast<NmtCommand>(frame.data[0])) {
    case NmtCommand::start: enter(NmtState::operational); return;
    case NmtCommand::stop: enter(NmtState::stopped); return;
    case NmtCommand::enter_pre_operational: enter(NmtState::pre_operational); return;
    case NmtCommand::reset_node: begin_reset(Reset::node); return;
    case NmtCommand::reset_communication: begin_reset(Reset::communication); return;
  }
  spdlog::warn("sim node {}: unknown NMT command {:02X}h ignored", node_id_, frame.data[0]);
}

}  // namespace lb::sim
