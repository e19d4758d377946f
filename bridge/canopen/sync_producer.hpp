#pragma once
// Produces SYNC (080h, no data) at a fixed period and tells its subscribers right after each one,
// which is when a master sends its synchronous RPDOs. Measures how far each SYNC's interval from
// the one before strays from the period (the loop's timing: a stalled loop sends late, and its
// timer's missed periods become one long interval), for diagnostics and metrics.

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <vector>

#include "base/histogram.hpp"
#include "canopen/bus_loop.hpp"

namespace lb::canopen {

class SyncProducer {
 public:
  // |interval - period| per SYNC, in seconds: 100 us (a loop on time) to 100 ms (5 periods of a
  // typical 20 ms line: a stall). docs/observability.md names them.
  static constexpr std::array<double, 10> kDeviationBounds{0.0001, 0.00025, 0.0005, 0.001, 0.0025,
                                                           0.005,  0.01,    0.025,  0.05,  0.1};
  using Deviations = Histogram<kDeviationBounds.size()>;

  SyncProducer(BusLoop& loop, std::chrono::microseconds period);

  // Before the loop starts.
  void on_sync(std::function<void()> subscriber) { subscribers_.push_back(std::move(subscriber)); }
  void start();  // loop thread or before the loop starts
  // Loop thread: a standby that takes the bus over continues the master's SYNC: the first one
  // `first` from now (a period after the master's last, or at once when that is past), then every
  // period.
  // sent: called once with the realtime stamp of that first SYNC (the takeover's measured gap).
  void resume(std::chrono::nanoseconds first, std::function<void(std::int64_t)> sent = {});
  std::chrono::microseconds period() const { return period_; }
  // Loop thread. Every SYNC the timer sent or tried to send (one the bus refused or held back is
  // counted by the loop), from the second after a start or resume on: that one's interval is no
  // period.
  const Deviations& deviations() const { return deviations_; }

 private:
  void tick();

  BusLoop& loop_;
  std::chrono::microseconds period_;
  BusLoop::TimerId timer_;
  std::vector<std::function<void()>> subscribers_;
  std::function<void(std::int64_t)> first_sent_;       // after resume(): the first SYNC's stamp
  std::chrono::steady_clock::time_point last_tick_{};  // the SYNC before; none after a (re)start
  Deviations deviations_{kDeviationBounds};
};

}  // namespace lb::canopen
