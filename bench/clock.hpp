#pragma once
// Time for the bench programs. Every latency is the difference of two CLOCK_REALTIME readings taken
// on one machine, one in the sending process and one in the receiving process; pacing uses
// CLOCK_MONOTONIC so a clock step cannot bunch up or stall the offered load.

#include <time.h>

#include <cstdint>

namespace lb::bench {

inline std::int64_t read_clock(clockid_t id) {
  timespec ts{};
  ::clock_gettime(id, &ts);
  return std::int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}
inline std::int64_t realtime_ns() { return read_clock(CLOCK_REALTIME); }
inline std::int64_t monotonic_ns() { return read_clock(CLOCK_MONOTONIC); }

// A send time travels as the low 32 bits of the nanosecond clock, because a CANopen object of the
// saw carries 32 bits. The difference of two such stamps is exact for latencies below 4.29 s.
inline std::uint32_t stamp32(std::int64_t ns) { return static_cast<std::uint32_t>(ns); }
inline std::int64_t elapsed_since(std::uint32_t stamp, std::int64_t now_ns) {
  return static_cast<std::uint32_t>(static_cast<std::uint32_t>(now_ns) - stamp);
}

// An absolute schedule: event i is due at start + i / rate. wait() sleeps until it is due (or
// nearly: see kSlackNs); an
// event that is late is not skipped (the offered load is what counts) and the lateness is kept,
// so a harness that cannot keep up shows it instead of silently offering less.
class Pacer {
 public:
  static constexpr std::int64_t kSlackNs = 100'000;
  explicit Pacer(double events_per_s) : period_ns_(1e9 / events_per_s) {}

  void start() { start_ns_ = monotonic_ns(); }
  void wait(std::uint64_t event) {
    const auto due = start_ns_ + static_cast<std::int64_t>(static_cast<double>(event) * period_ns_);
    const auto now = monotonic_ns();
    // Events due within kSlack go now: sleeping for each of 64000 frames/s would make the harness's
    // own wake-ups its largest cost. A CAN controller sends back to back too (~125 us per frame).
    if (now >= due - kSlackNs) {
      if (now < due) return;
      if (now - due > max_lag_ns_) max_lag_ns_ = now - due;
      return;
    }
    timespec ts{static_cast<time_t>(due / 1'000'000'000), static_cast<long>(due % 1'000'000'000)};
    while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) != 0) {
    }
  }
  double elapsed_s() const { return static_cast<double>(monotonic_ns() - start_ns_) / 1e9; }
  std::int64_t max_lag_ns() const { return max_lag_ns_; }

 private:
  double period_ns_;
  std::int64_t start_ns_ = 0;
  std::int64_t max_lag_ns_ = 0;
};

}  // namespace lb::bench
