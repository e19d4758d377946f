#pragma once
// The device side of NMT and heartbeat (CiA 301): boot-up message, the state machine driven by
// NMT commands (to this node or to all), resets, heartbeat producer. Every simulated device has one.

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>

#include "canopen/bus_loop.hpp"
#include "canopen/nmt.hpp"

namespace lb::sim {

class NmtSlave {
 public:
  enum class Reset { node, communication };
  struct Hooks {
    // Restores the power-on values the reset covers (and sets the heartbeat period), before the
    // boot-up message.
    std::function<void(Reset)> reset;
    std::function<void(canopen::NmtState from, canopen::NmtState to)> state_changed;
  };

  // Registers on the NMT identifier: before the loop starts.
  NmtSlave(canopen::BusLoop& loop, std::uint8_t node_id, Hooks hooks);

  // Loop thread (or before the loop starts): the reset, the boot-up message unless `announce` is
  // false (a device whose boot-up was lost), then pre-operational.
  void reset(Reset kind, bool announce = true);
  // false: resets by NMT command send no boot-up message (simulation: boot_up_after_nmt_reset).
  void announce_nmt_resets(bool announce) { announce_nmt_resets_ = announce; }
  // How long a reset by NMT command takes before the device is back (simulation: reset_time_ms):
  // meanwhile it is initialising and silent (no heartbeat, no SDO answer, no PDO) and takes no
  // NMT command; then it resets and sends its boot-up. Zero: at once.
  void set_reset_time(std::chrono::milliseconds time) { reset_time_ = time; }
  bool resetting() const { return pending_reset_.has_value(); }
  // 1017h: a period of 0 stops the heartbeat (CiA 301); the next one comes a period from now.
  void set_heartbeat_period(std::chrono::milliseconds period);
  // A communication error (a consumed heartbeat missing): 1029h sub 1's default 0 (CiA 301), an
  // operational device goes pre-operational; in any other state nothing changes.
  void communication_error();
  canopen::NmtState state() const { return state_; }
  std::uint8_t node_id() const { return node_id_; }

 private:
  void on_command(const can::CanFrame& frame);
  void begin_reset(Reset kind);
  void enter(canopen::NmtState state);
  void send_heartbeat();

  canopen::BusLoop& loop_;
  std::uint8_t node_id_;
  Hooks hooks_;
  canopen::BusLoop::TimerId heartbeat_timer_;
  canopen::BusLoop::TimerId reset_timer_;
  std::chrono::milliseconds reset_time_{0};
  std::optional<Reset> pending_reset_;  // an NMT reset under way (reset_time_)
  std::chrono::milliseconds heartbeat_period_{0};
  canopen::NmtState state_ = canopen::NmtState::boot_up;
  bool announce_nmt_resets_ = true;
};

}  // namespace lb::sim
