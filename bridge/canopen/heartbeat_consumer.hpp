#pragma once
// Supervises one remote node's heartbeat (CiA 301 1016h): every heartbeat or boot-up it sends,
// and whether one came within the configured timeout.
//
// The timeout is judged on the bus's own time (the frames' timestamps), not on the loop's: when
// the bus loop was held up (its process stopped, a slow handler), its timer fires before the
// frames that came meanwhile are read, and a device whose heartbeats wait in the queue is not
// lost. So when the timer fires while frames may still wait (BusLoop::input_pending) and no frame
// stamped after the deadline has been dispatched yet, or the timer itself fired late (the loop was
// stalled: a virtual bus's hub may not have forwarded what waits yet), the judgement waits for
// the queued frames: a heartbeat among them re-arms the timer as usual; a frame of anyone stamped
// after the deadline, with no heartbeat of this node before it, proves the loss. Bounded by
// kJudgementBound of the loop's time, so a clock stepped back or a bus that stays readable
// without frames still ends in a judgement. What the node is then (lost, or heard otherwise) is
// its listener's decision (RemoteNode, which also logs it: online and lost are key events,
// base/journal_event): the consumer only says that the heartbeat is missing.

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>

#include "canopen/bus_loop.hpp"
#include "canopen/nmt.hpp"

namespace lb::canopen {

class HeartbeatConsumer {
 public:
  // How long a judgement may wait for queued frames (loop time), and how often it looks again.
  static constexpr std::chrono::milliseconds kJudgementBound{2000};
  static constexpr std::chrono::milliseconds kJudgementRecheck{1};
  // A timer that fires this late means the loop did not run meanwhile.
  static constexpr std::chrono::milliseconds kLate{50};

  struct Listener {
    // Every frame on 700h + node-ID with a state byte (the boot-up message included), in order.
    // came_online: the first one, or the first after the heartbeat was declared missing for good.
    std::function<void(NmtState state, bool came_online)> on_heartbeat;
    // No heartbeat within the timeout, judged on the bus's time. Returns true when the node is
    // offline now; false keeps it online (keep_waiting() then says for how long).
    std::function<bool()> on_missing;
    std::function<void()> on_offline;                              // it went offline
    std::function<void(const can::CanFrame& frame)> on_malformed;  // a frame on 700h + n without data
  };

  HeartbeatConsumer(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds timeout, Listener listener);

  std::uint8_t node_id() const { return node_id_; }
  NmtState state() const { return state_; }  // as the last heartbeat reported it
  bool online() const { return online_; }
  std::int64_t last_heartbeat_ns() const { return last_heartbeat_ns_; }
  // Judgements that waited for queued frames (diagnostics).
  std::uint64_t judgements_deferred() const { return judgements_deferred_; }

  // Loop thread, by the listener of a missing heartbeat: stays online one more timeout from now.
  void keep_waiting();
  // Loop thread: offline now (the listener's bound on keeping it online).
  void declare_offline();

 private:
  void on_frame(const can::CanFrame& frame);
  void arm(std::chrono::milliseconds after);
  void on_timeout();

  BusLoop& loop_;
  std::uint8_t node_id_;
  std::chrono::milliseconds timeout_;
  Listener listener_;
  BusLoop::TimerId timer_;
  std::chrono::steady_clock::time_point due_{};                          // when the timer is meant to fire
  std::optional<std::chrono::steady_clock::time_point> deferred_since_;  // a judgement waits
  bool stalled_ = false;                                                 // it waits because the timer fired late
  std::int64_t deadline_ns_ = 0;                                         // bus time by which the next heartbeat is due
  NmtState state_ = NmtState::unknown;
  bool online_ = false;
  std::int64_t last_heartbeat_ns_ = 0;
  std::uint64_t judgements_deferred_ = 0;
};

}  // namespace lb::canopen
