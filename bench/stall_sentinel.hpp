#pragma once
// A host-stall sentinel for the jitter figures. On a shared virtual machine the hypervisor (or the
// kernel) now and then keeps a core from running anything for a millisecond or more; on such a host
// those stalls, not the program measured, set every p99.9. The sentinel tells them apart the way
// cyclictest and hwlatdetect do: a thread on the measured core, at a realtime priority above the
// program measured, wakes every millisecond and does nothing else. No user-space code at a lower
// priority can make it late, so when it wakes late the core was taken by the hypervisor, by
// interrupts or by kernel code that could not be preempted (PREEMPT_NONE: also a long system call
// of another thread on that core): a host stall. At the default threshold (500 µs) it sees every
// stall of 1.5 ms or more (one of its ticks falls in it and waits longer than the threshold), and
// a shorter one only when a tick falls early in it. The figures report every period, and beside
// them the periods no host stall touched.

#include <pthread.h>
#include <sched.h>
#include <time.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "clock.hpp"

namespace lb::bench {

// [begin, end] in CLOCK_REALTIME ns (the clock of frame stamps): from when the sentinel was due
// to when it ran.
struct HostStall {
  std::int64_t begin_ns;
  std::int64_t end_ns;
};

class StallSentinel {
 public:
  static constexpr std::int64_t kPeriodNs = 1'000'000;

  // Starts the sentinel on `cpu` at SCHED_FIFO `priority`; a wake-up later than `threshold_ns` is a
  // stall. Throws at start-up if the thread cannot be placed or given its priority: without them it
  // would measure nothing.
  StallSentinel(int cpu, int priority, std::int64_t threshold_ns)
      : cpu_(cpu),
        priority_(priority),
        threshold_ns_(threshold_ns),
        thread_([this](std::stop_token stop) { run(stop); }) {
    placed_.wait(Placement::pending);
    if (placed_.load() == Placement::failed) {
      thread_.join();
      throw std::runtime_error("stall sentinel: cannot run on cpu " + std::to_string(cpu) + " at SCHED_FIFO " +
                               std::to_string(priority));
    }
  }
  StallSentinel(const StallSentinel&) = delete;
  StallSentinel& operator=(const StallSentinel&) = delete;
  ~StallSentinel() { stop(); }

  // Stops the sentinel; the stalls it saw, in time order.
  const std::vector<HostStall>& stop() {
    if (thread_.joinable()) {
      thread_.request_stop();
      thread_.join();
    }
    return stalls_;
  }

 private:
  void run(const std::stop_token& stop) {
    // Placed before the first wake-up is timed: until then it may run anywhere, at any priority.
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu_, &set);
    const sched_param param{.sched_priority = priority_};
    const bool placed = ::pthread_setaffinity_np(::pthread_self(), sizeof set, &set) == 0 &&
                        ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &param) == 0;
    placed_.store(placed ? Placement::done : Placement::failed);
    placed_.notify_one();
    if (!placed) return;
    stalls_.reserve(100'000);  // before the measurement: the loop below allocates only if more come
    auto due = monotonic_ns();
    while (!stop.stop_requested()) {
      due += kPeriodNs;
      const timespec at{static_cast<time_t>(due / 1'000'000'000), static_cast<long>(due % 1'000'000'000)};
      ::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, nullptr);
      const auto now = monotonic_ns();
      if (now - due > threshold_ns_) {
        const auto end = realtime_ns();
        stalls_.push_back({end - (now - due), end});
        due = now;  // one stall is one entry: no catch-up wake-ups for the periods it swallowed
      }
    }
  }

  enum class Placement { pending, done, failed };
  int cpu_;
  int priority_;
  std::int64_t threshold_ns_;
  std::vector<HostStall> stalls_;
  std::atomic<Placement> placed_{Placement::pending};
  std::jthread thread_;  // last: it starts when everything it uses exists
};

// Whether a host stall touched the event stamped `at`: a stall that ended within `window_ns` before
// it (the event was due during the stall, or the stall left a backlog it waited behind) or that
// began before it and ended after. `stalls` in time order.
inline bool stalled(std::span<const HostStall> stalls, std::int64_t at, std::int64_t window_ns) {
  const auto after = std::lower_bound(stalls.begin(), stalls.end(), at - window_ns,
                                      [](const HostStall& s, std::int64_t t) { return s.end_ns < t; });
  return after != stalls.end() && after->begin_ns <= at;
}

// The sentinel's command-line options, the same in every bench program that has one.
struct SentinelOptions {
  int cpu = -1;  // none
  int priority = 41;
  double threshold_us = 500;
  double window_us = 2000;

  void add_to(CLI::App& cli, const std::string& measured) {
    cli.add_option("--sentinel-cpu", cpu, "the core of " + measured + ", where the host-stall sentinel runs (-1: none)")
        ->capture_default_str();
    cli.add_option("--sentinel-priority", priority, "the sentinel's SCHED_FIFO priority: above " + measured + "'s")
        ->check(CLI::Range(1, 99))
        ->capture_default_str();
    cli.add_option("--stall-threshold-us", threshold_us, "a sentinel wake-up this late is a host stall")
        ->check(CLI::Range(50.0, 100000.0))
        ->capture_default_str();
    cli.add_option("--stall-window-us", window_us, "an event within this time after a host stall was touched by it")
        ->check(CLI::Range(0.0, 100000.0))
        ->capture_default_str();
  }
  std::int64_t window_ns() const { return static_cast<std::int64_t>(window_us * 1e3); }
  // Starts the sentinel if asked for (into `sentinel`); false, with the reason on stderr, if it cannot run.
  bool start(std::optional<StallSentinel>& sentinel, const char* program) const {
    if (cpu < 0) return true;
    try {
      sentinel.emplace(cpu, priority, static_cast<std::int64_t>(threshold_us * 1e3));
      return true;
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s: %s\n", program, e.what());
      return false;
    }
  }
};

}  // namespace lb::bench
