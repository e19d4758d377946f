#pragma once
// When a device is booted (master role): at start-up, after every boot-up, and whenever the
// master no longer knows what its object dictionary holds: its heartbeat came back after a loss,
// or it reports a state it was not told to take (it may have been reset without its boot-up
// reaching the master, e.g. during a bus-off or a cable fault). Never a bare NMT start of such a
// device: it is booted again (CiA 302-2 "boot slave"), or reset so that its boot-up starts the
// boot, as the line configures. A device that fails its boot is tried again after the retry
// interval; one that keeps booting (a boot-up storm) is reported and backed off.

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <string_view>

#include "base/repeat_log.hpp"
#include "canopen/boot_sequence.hpp"
#include "canopen/remote_node.hpp"

namespace lb::canopen {

enum class RecoveryAction { reboot, reset_node };

// The master's view of one device, as diagnostics name it (derived from the boot, the error
// control's wait and the node's heartbeat and commands).
enum class NodeState {
  unknown,              // not heard yet
  booting,              // a boot is checking and configuring it
  boot_failed,          // the last boot failed; retried after boot_retry_ms or a back-off
  running_unmanaged,    // its boot failed while it runs: left running, reported, not started by the bridge
  operational,          // started by the bridge, heard operational
  stopped_by_operator,  // an operator's NMT stop or pre-operational, kept
  resetting,            // an NMT reset was sent: waiting for its boot-up
  lost,                 // no heartbeat within its timeout
};
std::string_view to_string(NodeState state);

class ErrorControl {
 public:
  struct Settings {
    RecoveryAction on_state_unknown = RecoveryAction::reboot;
    std::chrono::milliseconds retry{5000};  // after a failed boot
    // A storm: this many boot-ups or lost states within the window. Each further one doubles the
    // wait before the next boot, up to max_backoff.
    unsigned storm_count = 5;
    std::chrono::seconds storm_window{60};
    std::chrono::seconds max_backoff{300};
    // After an NMT reset: how long to wait for the boot-up before booting anyway.
    std::chrono::milliseconds reset_bound{2000};
  };
  struct Counters {
    std::uint32_t boots = 0;           // attempts begun
    std::uint32_t boots_started = 0;   // attempts that ended with NMT start
    std::uint32_t boot_failures = 0;
    std::uint32_t state_unknown = 0;   // lost-and-back and unexpected states
    std::uint32_t storms = 0;          // times a storm began
  };
  using Listener = std::function<void(const BootReport&)>;  // every attempt that ends

  // Before the loop starts or on the loop thread.
  ErrorControl(BusLoop& loop, RemoteNode& node, BootSequence& boot, Settings settings, Listener listener);

  void start();  // loop thread: the first boot
  // Loop thread: an NMT reset was sent to the device. A reset always leads to a boot: its boot-up
  // starts one, and if none is believed within kResetBound (a lost boot-up), a boot begins
  // anyway; the device is never taken for started meanwhile. An operator's reset also ends a
  // boot-up storm's back-off: it is a deliberate action, and the device is booted at its boot-up.
  void reset_sent(bool by_operator);

  // Loop thread: what diagnostics show (the boot's step, a pending retry, a storm).
  std::string state() const;
  NodeState node_state() const;
  const Counters& counters() const { return counters_; }

 private:
  void on_event(RemoteNode::Event event, NmtState reported);
  bool boot_under_way() const;
  void recover(const char* why);
  void boot_now(const std::string& why);
  void boot_after(std::chrono::milliseconds delay, const std::string& why);
  // Records a boot-up or lost state; true (and the delay armed) when it makes a storm.
  bool storm();
  void finished(const BootReport& report);

  BusLoop& loop_;
  RemoteNode& node_;
  BootSequence& boot_;
  Settings settings_;
  Listener listener_;
  BusLoop::TimerId timer_;
  BusLoop::TimerId reset_timer_;  // bounds the wait for the boot-up after a reset
  std::deque<std::chrono::steady_clock::time_point> recent_;
  std::chrono::milliseconds backoff_{0};
  std::string waiting_;  // why the next boot is pending, or empty
  bool unmanaged_ = false;  // its boot failed while it runs: no retry until an event
  bool resetting_ = false;  // an NMT reset was sent, its boot-up not seen yet
  RepeatLog boot_log_;  // an absent device is tried every retry interval: the same line once a minute
  Counters counters_;
};

}  // namespace lb::canopen
