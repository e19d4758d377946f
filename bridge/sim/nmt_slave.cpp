#include "sim/nmt_slave.hpp"

#include <spdlog/spdlog.h>

namespace lb::sim {

using canopen::NmtCommand;
using canopen::NmtState;

NmtSlave::NmtSlave(canopen::BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_period,
                   std::function<void()> on_reset_node)
    : loop_(loop), node_id_(node_id), heartbeat_period_(heartbeat_period), on_reset_node_(std::move(on_reset_node)) {
  heartbeat_timer_ = loop_.create_timer([this] { send_heartbeat(); });
  loop_.on_frame(canopen::cob::nmt, [this](const can::CanFrame& f) { on_command(f); });
}

void NmtSlave::boot() {
  state_ = NmtState::boot_up;
  send_heartbeat();  // the boot-up message is a heartbeat with state 0
  state_ = NmtState::pre_operational;
  set_heartbeat_period(heartbeat_period_);
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

void NmtSlave::on_command(const can::CanFrame& frame) {
  if (frame.len != 2 || (frame.data[1] != 0 && frame.data[1] != node_id_)) return;
  switch (static_cast<NmtCommand>(frame.data[0])) {
    case NmtCommand::start: state_ = NmtState::operational; break;
    case NmtCommand::stop: state_ = NmtState::stopped; break;
    case NmtCommand::enter_pre_operational: state_ = NmtState::pre_operational; break;
    case NmtCommand::reset_node:
      if (on_reset_node_) on_reset_node_();
      boot();
      return;
    case NmtCommand::reset_communication: boot(); return;
    default:
      spdlog::warn("sim node {}: unknown NMT command {:02X}h ignored", node_id_, frame.data[0]);
      return;
  }
  send_heartbeat();  // report the new state at once rather than at the next period
}

}  // namespace lb::sim
