#pragma once
// Produces SYNC (080h, no data) at a fixed period and tells its subscribers right after each one,
// which is when a master sends its synchronous RPDOs.

#include <chrono>
#include <functional>
#include <vector>

#include "canopen/bus_loop.hpp"

namespace lb::canopen {

class SyncProducer {
 public:
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

 private:
  void tick();

  BusLoop& loop_;
  std::chrono::microseconds period_;
  BusLoop::TimerId timer_;
  std::vector<std::function<void()>> subscribers_;
  std::function<void(std::int64_t)> first_sent_;  // after resume(): the first SYNC's stamp
};

}  // namespace lb::canopen
