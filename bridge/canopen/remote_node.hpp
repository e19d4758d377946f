#pragma once
// The master's view of one device: heartbeat supervision, emergencies and active errors, counters
// for diagnostics, and, in the master role, NMT commands — start at start-up, after every boot-up
// and whenever a started device reports pre-operational.

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/emcy.hpp"
#include "canopen/heartbeat_consumer.hpp"
#include "canopen/nmt.hpp"

namespace lb::canopen {

class RemoteNode {
 public:
  struct Stats {
    std::uint32_t boot_ups = 0;
    std::uint64_t pdos_received = 0;
    std::uint64_t pdos_sent = 0;
    std::uint64_t pdo_length_errors = 0;
    std::uint64_t emergencies = 0;
    std::uint64_t range_warnings = 0;
  };
  using ChangeListener = std::function<void(NmtState state, bool online)>;
  using EmergencyListener = std::function<void(const Emergency&)>;

  // may_transmit = false for the monitor role: the node is observed, never commanded.
  RemoteNode(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_timeout, bool may_transmit);

  // Registration before the loop starts.
  void on_change(ChangeListener listener) { listeners_.push_back(std::move(listener)); }
  void on_emergency(EmergencyListener listener) { emcy_listeners_.push_back(std::move(listener)); }
  // Replaces the plain NMT start after a boot-up (e.g. configure by SDO first, then start).
  void on_boot_up(std::function<void()> handler) { boot_handler_ = std::move(handler); }

  void start();  // loop thread: the first boot handling (or NMT start)
  // Loop thread. Refused with the reason on a monitor bus.
  Result<void> command(NmtCommand command);

  std::uint8_t node_id() const { return heartbeat_.node_id(); }
  NmtState state() const { return heartbeat_.state(); }
  bool online() const { return heartbeat_.online(); }
  std::int64_t last_heartbeat_ns() const { return heartbeat_.last_heartbeat_ns(); }
  bool may_transmit() const { return may_transmit_; }
  // Started by this bridge and alive: the condition for sending it RPDOs.
  bool ready_for_pdos() const { return started_ && online() && state() == NmtState::operational; }
  const ActiveErrors& errors() const { return errors_; }
  Stats& stats() { return stats_; }
  const Stats& stats() const { return stats_; }

 private:
  void booted();
  void changed(NmtState state, bool online);
  void on_emcy_frame(const can::CanFrame& frame);

  BusLoop& loop_;
  bool may_transmit_;
  bool started_ = false;
  Stats stats_;
  ActiveErrors errors_;
  std::function<void()> boot_handler_;
  std::vector<ChangeListener> listeners_;
  std::vector<EmergencyListener> emcy_listeners_;
  HeartbeatConsumer heartbeat_;
};

}  // namespace lb::canopen
