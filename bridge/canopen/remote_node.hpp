#pragma once
// One device as heard and addressed on the bus: heartbeat supervision, the NMT state it was told
// to be in, emergencies and active errors, counters for diagnostics, and the PDOs its last boot
// left in use. It tells its drivers (NodeDriver, the gateways and, master role, the node state
// machine) what it hears, including what makes the device's state unknown to the master (a
// boot-up, a lost heartbeat, a state it was not told to take); what to do about it is the node
// state machine's business (canopen/node_state_machine.hpp).
//
// Beliefs need evidence (master role; docs/canopen-master.md "What the master believes, and on
// what evidence"). Anyone on the bus can send a frame on 700h + node-ID, so one frame there
// proves nothing. A state the device was told to take is believed from its first heartbeat that
// reports it, and so is the first heartbeat after the device was offline. Any other new state,
// and a boot-up, is believed only when the device's heartbeat reports it consistently: two
// heartbeats of that state at least one producer period apart (1017h as its last boot read it;
// half the heartbeat timeout when unknown), and no heartbeat of another state in between; for a
// boot-up, the boot-up message and a just-booted state reported since, at least a period after
// it. A real device reports its state every period, so it is believed after one to three beats;
// a spoofed frame next to a running device is contradicted by the device's own heartbeat within a
// period, and changes nothing. state() is the believed state. A boot-up followed by silence is believed
// (a device whose heartbeat is off at power-on); a boot-up followed by "operational" is not,
// unless the device starts itself (believe_every_boot_up). The monitor role believes every frame
// at once: it only watches.
//
// A heartbeat that stops while the device is still heard by frames of its own (TPDOs, EMCY, SDO
// answers) is not taken for a lost device: its heartbeat producer time may have been changed
// under the bridge. The node stays online (and what it is to the node state machine stays as it
// was) while the check its master registered (on_heartbeat_missing: read 1017h, write back what
// its last boot left there) runs, and one heartbeat timeout after a write-back; then, without a
// heartbeat, it is lost as any silent device.

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "base/journal_event.hpp"
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
    // A boot-up that the heartbeats after it contradicted (one saying operational, of a device that
    // does not start itself).
    std::uint32_t boot_ups_not_believed = 0;
    // A state reported (not the believed one, not the one commanded) that the next heartbeats
    // contradicted before it was reported consistently over a producer period.
    std::uint32_t states_not_believed = 0;
    // Its heartbeat timed out while it was heard by other frames of its own: kept online while its
    // 1017h was checked (NodeStateMachine::Counters::heartbeat_producer_rewrites: written back).
    std::uint32_t heartbeats_missing_while_heard = 0;
    // Of emergencies (well-formed EMCYs, resets included): per class of the code (EmcyClass).
    std::array<std::uint64_t, kEmcyClasses> emergencies_by_class{};
  };
  using Event = NodeEvent;
  using StartFacts = canopen::StartFacts;
  // How long a device heard without a heartbeat stays online while its heartbeat producer is
  // checked, at most (the check's SDO exchanges end sooner by their own timeouts).
  static constexpr std::chrono::seconds kHeartbeatCheckBound{10};

  // may_transmit = false for the monitor role: the node is observed, never commanded.
  RemoteNode(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_timeout, bool may_transmit);

  // Before the loop starts: the device enters operational by itself at power-on, so a boot-up
  // followed by "operational" is believed too (otherwise it is a spoofed frame or a fault).
  void believe_every_boot_up(bool believe) { believe_every_boot_up_ = believe; }

  // Before the loop starts: the drivers are told in the order they were attached.
  void attach(NodeDriver& driver) { drivers_.push_back(&driver); }

  // Before the loop starts: the line, bus and device names its key events carry (base/journal_event:
  // online, lost, EMCY, a boot that failed). The node-ID is its own.
  void name_events(journal::Where where) {
    where.node = node_id();
    where_ = std::move(where);
  }
  const journal::Where& where() const { return where_; }

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
  // Loop thread: a standby that took the bus over adopts the device in the state the master before
  // left it (operational, or held stopped / pre-operational): configured, and that state taken for
  // commanded, without a frame.
  void adopt(NmtState commanded) {
    configured_ = true;
    commanded_ = commanded;
    confirmed_ = state() == commanded;
    commanded_at_ = std::chrono::steady_clock::now();
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
  // The state the master believes (see the top of this file); reported_state() is the last
  // heartbeat's, believed or not.
  NmtState state() const { return believed_; }
  NmtState reported_state() const { return heartbeat_.state(); }
  bool online() const { return heartbeat_.online(); }
  // Loop thread, by the boot: the heartbeat producer time (1017h) as the device has it, the period
  // a new state must be reported over to be believed; nullopt or 0: unknown (half the timeout).
  void set_heartbeat_producer(std::optional<std::chrono::milliseconds> period) { producer_period_ = period; }
  // The period a new state must be reported over.
  std::chrono::nanoseconds evidence_period() const;
  // Before the loop starts, by the node's master (NodeStateMachine): what checks a device whose
  // heartbeat stopped while it is still heard by other frames of its own; it ends by calling
  // heartbeat_check_done. Without one such a device is lost as any other.
  void on_heartbeat_missing(std::function<void()> check) { heartbeat_check_ = std::move(check); }
  // Loop thread: how the check ended. written_back: it found the heartbeat producer changed and
  // wrote it back (the heartbeat is waited for one more timeout); not_the_cause (1017h holds what
  // the last boot left, or cannot be read or written): the device is lost now; abandoned (a boot
  // or a reset began meanwhile): lost at the next timeout unless its heartbeat comes.
  enum class HeartbeatCheck { written_back, not_the_cause, abandoned };
  void heartbeat_check_done(HeartbeatCheck result);
  // Loop thread: a boot-up message came and is not judged yet (the heartbeats that follow decide).
  bool boot_up_pending() const { return boot_up_pending_; }
  // Loop thread: its heartbeat timed out while it is heard: online while the check runs.
  bool heartbeat_missing() const { return missing_; }
  // Heartbeat timeouts that waited for frames queued on the bus (HeartbeatConsumer).
  std::uint64_t heartbeat_judgements_deferred() const { return heartbeat_.judgements_deferred(); }
  // Loop thread: the device sent a frame of its own (heartbeat or boot-up, EMCY, SDO answer, a
  // TPDO reported through heard_frame) within its heartbeat timeout. What the stop path asks:
  // a device that is heard takes a stop, whatever the master believes about its state.
  bool heard() const;
  // Loop thread: heard(), counting the frames that wait on the bus too (BusLoop::catch_up): what
  // refuses a stop asks this. A request and the device's first frame after a silence may arrive
  // in the same instant (the fault campaign: a restarted bridge, the feeder box's heartbeat every
  // 5 s, its stop request in the same millisecond as that heartbeat, refused as not heard).
  bool heard_now() {
    if (heard()) return true;
    return loop_.catch_up() && heard();
  }
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
  struct Candidate {
    NmtState state;
    std::int64_t since_ns;  // its first heartbeat reporting it (bus time)
  };
  // What a heartbeat makes the master believe: the state, and whether the pending boot-up stands.
  struct Judgement {
    NmtState believed;
    bool boot_up = false;
  };
  void heartbeat(NmtState state, bool came_online);
  Judgement judge(NmtState state, bool came_online);
  Judgement judge_boot_up(NmtState state, std::int64_t timestamp_ns);
  void boot_up_seen(bool came_online);
  bool evidence(NmtState state, std::int64_t timestamp_ns);
  void not_believed(const Candidate& candidate, NmtState contradicted_by);
  void booted(NmtState state);
  bool missing();
  void went_offline();
  void check_commanded(NmtState state);
  void emit(Event event);
  void on_emcy_frame(const can::CanFrame& frame);

  BusLoop& loop_;
  bool may_transmit_;
  std::chrono::milliseconds heartbeat_timeout_;
  bool configured_ = false;
  NmtState commanded_ = NmtState::unknown;  // unknown: not commanded since its last boot-up
  bool confirmed_ = false;                  // a heartbeat reported the commanded state since
  std::chrono::steady_clock::time_point commanded_at_{};
  bool believe_every_boot_up_ = false;
  std::optional<NmtCommand> hold_;  // an operator's stop or pre-operational, kept
  NmtState believed_ = NmtState::unknown;
  bool boot_up_pending_ = false;  // a boot-up frame, not yet confirmed by the state that follows
  // The master commanded the device while a boot-up was pending: what it reports next follows the
  // command, and the boot-up stands.
  bool boot_up_then_commanded_ = false;
  std::int64_t boot_up_ns_ = 0;         // the pending boot-up message (bus time)
  std::optional<Candidate> candidate_;  // a new state, reported but not (yet) believed
  std::optional<std::chrono::milliseconds> producer_period_;
  std::function<void()> heartbeat_check_;
  bool missing_ = false;   // its heartbeat timed out while it is heard: online while checked
  bool checking_ = false;  // the check runs
  std::chrono::steady_clock::time_point missing_since_{};
  Stats stats_;
  ActiveErrors errors_;
  std::vector<PdoInUse> pdos_;
  std::vector<NodeDriver*> drivers_;
  LogRate emcy_log_;
  LogRate malformed_log_;
  LogRate spoof_log_{1};
  std::string set_values_at_start_;
  journal::Where where_;
  std::int64_t last_heard_ns_ = 0;  // the newest frame of the device's own (its bus's timestamps)
  HeartbeatConsumer heartbeat_;
};

}  // namespace lb::canopen
