#pragma once
// The device side of NMT and heartbeat: boot-up message, state machine driven by NMT commands,
// heartbeat producer. Every simulated device has one.

#include <chrono>
#include <cstdint>
#include <functional>

#include "canopen/bus_loop.hpp"
#include "canopen/nmt.hpp"

namespace lb::sim {

class NmtSlave {
 public:
  // on_reset runs before the new boot-up on "reset node" (application values to defaults).
  NmtSlave(canopen::BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_period,
           std::function<void()> on_reset_node);

  void boot();  // loop thread (or before the loop starts): boot-up, then pre-operational
  // 1017h written: a period of 0 stops the heartbeat (CiA 301).
  void set_heartbeat_period(std::chrono::milliseconds period);
  canopen::NmtState state() const { return state_; }
  std::uint8_t node_id() const { return node_id_; }

 private:
  void on_command(const can::CanFrame& frame);
  void send_heartbeat();

  canopen::BusLoop& loop_;
  std::uint8_t node_id_;
  std::chrono::milliseconds heartbeat_period_;
  std::function<void()> on_reset_node_;
  canopen::BusLoop::TimerId heartbeat_timer_;
  canopen::NmtState state_ = canopen::NmtState::boot_up;
};

}  // namespace lb::sim
