#pragma once
// One device as heard and addressed on the bus: heartbeat supervision, the NMT state it was told
// to be in, emergencies and active errors, counters for diagnostics, and the PDOs its last boot
// left in use. It tells its drivers (NodeDriver, the gateways and, master role, the node state
// machine) what it hears, including what makes the device's state unknown to the master (a
// boot-up, a lost heartbeat, a state it was not told to take); what to do about it is the node
// state machine's business (canopen/node_state_machine.hpp).

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "base/log_rate.hpp"
#include "base/result.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/emcy.hpp"
#include "canopen/heartbeat_consumer.hpp"
#include "canopen/nmt.hpp"
#include "canopen/node_driver.hpp"
#include "canopen/pdo_parameters.hpp"

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
    std::uint64_t malformed_emergencies = 0;  // EMCYs not 8 bytes long (ignored)
    std::uint64_t malformed_heartbeats = 0;   // heartbeats without a state byte (ignored)
    std::uint32_t boot_ups_not_believed = 0;  // a boot-up, then a heartbeat saying operational
  };
  using Event = NodeEvent;
  using StartFacts = canopen::StartFacts;

  // may_transmit = false for the monitor role: the node is observed, never commanded.
  RemoteNode(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_timeout, bool may_transmit);

  // Before the loop starts: the device enters operational by itself at power-on, so a boot-up
  // followed by "operational" is believed too (otherwise it is a spoofed frame or a fault).
  void believe_every_boot_up(bool believe) { believe_every_boot_up_ = believe; }

  // Before the loop starts: the drivers are told in the order they were attached.
  void attach(NodeDriver& driver) { drivers_.push_back(&driver); }

  // Loop thread. Refused with the reason on a monitor bus. Records the state the device must take;
  // after a reset the device is no longer configured (its boot-up, or the node state machine's bound on
  // waiting for it, starts a boot).
  Result<void> command(NmtCommand command);
  // Loop thread: an operator's NMT stop or enter pre-operational is kept until an operator starts
  // (or resets) the device: every boot in between configures it and puts it back in that state
  // instead of starting it, whatever happens to its heartbeat.
  void hold(NmtCommand command) {
    hold_ = command;
    for (auto* d : drivers_) d->on_hold(hold_);
  }
  void release_hold() {
    if (!hold_) return;
    hold_.reset();
    for (auto* d : drivers_) d->on_hold(hold_);
  }
  const std::optional<NmtCommand>& operator_hold() const { return hold_; }
  // Loop thread: the boot passed (the device holds the configuration), or a boot begins or failed:
  // then what the device was told before no longer counts (it is pre-operational while booted).
  void set_configured(bool configured) {
    configured_ = configured;
    if (!configured) commanded_ = NmtState::unknown;
  }
  // Loop thread, by the boot: the PDOs from now on; the first driver's refusal is returned.
  Result<void> use_pdos(std::span<const PdoInUse> pdos);
  // Loop thread, by the boot, right before NMT start.
  void starting(const StartFacts& facts) {
    for (auto* d : drivers_) d->on_start(facts);
  }
  // Loop thread: tells every driver (the state machine's transitions, the boot's end, the SYNC).
  template <class Hook>
  void tell(Hook hook) {
    for (auto* d : drivers_) hook(*d);
  }
  // What the last start did with the set values in force (diagnostics), and the gateway's note of it.
  const std::string& set_values_at_start() const { return set_values_at_start_; }
  void note_set_values_at_start(std::string note) { set_values_at_start_ = std::move(note); }

  std::uint8_t node_id() const { return heartbeat_.node_id(); }
  NmtState state() const { return heartbeat_.state(); }
  bool online() const { return heartbeat_.online(); }
  // Loop thread: the device sent a frame of its own (heartbeat or boot-up, EMCY, SDO answer, a
  // TPDO reported through heard_frame) within its heartbeat timeout. What the stop path asks:
  // a device that is heard takes a stop, whatever the master believes about its state.
  bool heard() const;
  std::int64_t last_heard_ns() const { return last_heard_ns_; }
  // Loop thread: a frame only the device sends (its TPDOs, as the gateway decodes them).
  void heard_frame(std::int64_t timestamp_ns) { last_heard_ns_ = std::max(last_heard_ns_, timestamp_ns); }
  std::int64_t last_heartbeat_ns() const { return heartbeat_.last_heartbeat_ns(); }
  std::chrono::milliseconds heartbeat_timeout() const { return heartbeat_timeout_; }
  bool may_transmit() const { return may_transmit_; }
  bool configured() const { return configured_; }
  NmtState commanded_state() const { return commanded_; }
  // Configured by this bridge, told to be operational and alive: the condition for sending RPDOs.
  bool ready_for_pdos() const {
    return configured_ && commanded_ == NmtState::operational && online() && state() == NmtState::operational;
  }
  const std::vector<PdoInUse>& pdos() const { return pdos_; }
  const ActiveErrors& errors() const { return errors_; }
  // Loop thread: changes the active-error list (with what the device lists, say) and tells the
  // drivers.
  template <class Change>
  void update_errors(Change change) {
    change(errors_);
    for (auto* d : drivers_) d->on_errors();
  }
  Stats& stats() { return stats_; }
  const Stats& stats() const { return stats_; }

 private:
  void boot_up_seen();
  void booted();
  void changed(NmtState state, bool online);
  void heartbeat(NmtState state);
  void check_state(NmtState state);
  void emit(Event event);
  void on_emcy_frame(const can::CanFrame& frame);

  BusLoop& loop_;
  bool may_transmit_;
  std::chrono::milliseconds heartbeat_timeout_;
  bool configured_ = false;
  NmtState commanded_ = NmtState::unknown;  // unknown: not commanded since its last boot-up
  bool confirmed_ = false;                  // a heartbeat reported the commanded state since
  std::chrono::steady_clock::time_point commanded_at_{};
  bool was_online_ = false;
  bool believe_every_boot_up_ = false;
  std::optional<NmtCommand> hold_;  // an operator's stop or pre-operational, kept
  bool boot_up_pending_ = false;    // a boot-up frame, not yet confirmed by the state that follows
  Stats stats_;
  ActiveErrors errors_;
  std::vector<PdoInUse> pdos_;
  std::vector<NodeDriver*> drivers_;
  LogRate emcy_log_;
  LogRate malformed_log_;
  LogRate spoof_log_{1};
  std::string set_values_at_start_;
  std::int64_t last_heard_ns_ = 0;  // the newest frame of the device's own (its bus's timestamps)
  HeartbeatConsumer heartbeat_;
};

}  // namespace lb::canopen
