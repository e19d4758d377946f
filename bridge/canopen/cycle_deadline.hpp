#pragma once
// The publication deadline of a SYNC cycle (status_publish: per_cycle, docs/dds-contract.md): the
// synchronous TPDOs of one cycle belong together (a device samples at the SYNC and sends after it),
// so a device's status waits for the rest of its cycle, but no longer than the cycle: a PDO that
// stays missing must not hold the others back. What still waits at the next SYNC, or one interval
// after the last SYNC when no next one came, runs. Not a shorter deadline: on a fully loaded bus
// the cycle's TPDOs fill the whole cycle, every device's TPDO1 (lower identifiers win the
// arbitration) before any TPDO2, so a device's last TPDO comes about half a cycle after its first
// (measured: with half an interval as the deadline a saturated bus got one sample per frame).
//
// The SYNC is what the bus carried (a monitor, a standby) or what this bridge produced (a master,
// which never receives its own frames): whoever sees it calls seen(). The interval is the last one
// measured between two SYNCs, the configured period until two were seen.

#include <chrono>
#include <cstdint>
#include <vector>

#include "canopen/bus_loop.hpp"

namespace lb::canopen {

class CycleDeadline {
 public:
  using WaiterId = std::size_t;

  CycleDeadline(BusLoop& loop, std::chrono::microseconds configured_period);
  CycleDeadline(const CycleDeadline&) = delete;
  CycleDeadline& operator=(const CycleDeadline&) = delete;

  // Before the loop starts: what runs when a waiter's cycle ends.
  WaiterId create_waiter(BusLoop::Task on_deadline);
  // Loop thread. A SYNC went out or came in: the cycle before is over, a new one is open.
  void seen();
  // Loop thread: a SYNC began the current cycle and its deadline has not passed.
  bool open() const { return open_; }
  // Loop thread: run this waiter at the deadline (once however often it is asked).
  void wait(WaiterId id);
  // Loop thread: the deadline of the open cycle after its SYNC.
  std::chrono::nanoseconds deadline() const { return interval_; }

 private:
  void close();

  BusLoop& loop_;
  BusLoop::TimerId timer_;
  std::chrono::nanoseconds interval_;
  std::chrono::steady_clock::time_point last_sync_{};
  bool open_ = false;
  struct Waiter {
    BusLoop::Task callback;
    bool waiting = false;
  };
  std::vector<Waiter> waiters_;
  std::vector<WaiterId> waiting_;
};

}  // namespace lb::canopen
