// bench-timer-floor: the floor under the SYNC jitter figure. A bare periodic timer (absolute
// clock_nanosleep, as cyclictest does), run where the bridge runs: how late the machine wakes a
// thread that does nothing else. No program's SYNC can be steadier than this on the same core.
// With --sentinel-cpu, also over the wake-ups no host stall touched (stall_sentinel.hpp): how
// steady the core is between the host's stalls.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <vector>

#include "clock.hpp"
#include "stall_sentinel.hpp"

namespace bench = lb::bench;

int main(int argc, char** argv) {
  CLI::App cli{"bench-timer-floor: wake-up lateness of a bare periodic timer"};
  double duration_s = 60;
  double period_us = 20000;
  bench::SentinelOptions sentinel_options;
  cli.add_option("--duration", duration_s, "seconds to measure")->check(CLI::Range(1.0, 7200.0))->capture_default_str();
  cli.add_option("--period-us", period_us, "the timer's period")->check(CLI::Range(100.0, 1e6))->capture_default_str();
  sentinel_options.add_to(cli, "this timer");
  CLI11_PARSE(cli, argc, argv);

  const auto period_ns = static_cast<std::int64_t>(period_us * 1e3);
  const auto n = static_cast<std::size_t>(duration_s * 1e9 / static_cast<double>(period_ns));
  std::vector<double> late_us;
  std::vector<std::int64_t> woke_at;  // CLOCK_REALTIME, the sentinel's clock
  late_us.reserve(n);
  woke_at.reserve(n);
  std::optional<bench::StallSentinel> sentinel;
  if (!sentinel_options.start(sentinel, "bench-timer-floor")) return 1;
  std::int64_t due = bench::monotonic_ns();
  for (std::size_t i = 0; i < n; ++i) {
    due += period_ns;
    const timespec at{static_cast<time_t>(due / 1'000'000'000), static_cast<long>(due % 1'000'000'000)};
    ::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, nullptr);
    late_us.push_back(static_cast<double>(bench::monotonic_ns() - due) / 1e3);
    woke_at.push_back(bench::realtime_ns());
  }
  std::vector<double> clean_us;
  if (sentinel) {
    const auto& stalls = sentinel->stop();
    for (std::size_t i = 0; i < late_us.size(); ++i) {
      if (!bench::stalled(stalls, woke_at[i], sentinel_options.window_ns())) clean_us.push_back(late_us[i]);
    }
    std::sort(clean_us.begin(), clean_us.end());
    std::fputs(fmt::format("floor_host_stalls={}\nfloor_clean_wakeups={}\n", stalls.size(), clean_us.size()).c_str(), stdout);
  }
  std::sort(late_us.begin(), late_us.end());
  const auto at = [](const std::vector<double>& sorted, double p) {
    if (sorted.empty()) return 0.0;
    const auto i = static_cast<std::size_t>(std::ceil(p / 100.0 * static_cast<double>(sorted.size()))) - 1;
    return sorted[std::min(i, sorted.size() - 1)];
  };
  std::fputs(fmt::format("floor_wakeups={}\nfloor_p50_us={:.1f}\nfloor_p99_us={:.1f}\nfloor_p999_us={:.1f}\nfloor_max_us={:.1f}\n",
                         late_us.size(), at(late_us, 50), at(late_us, 99), at(late_us, 99.9), at(late_us, 100))
                 .c_str(),
             stdout);
  if (sentinel) {
    std::fputs(fmt::format("floor_clean_p50_us={:.1f}\nfloor_clean_p99_us={:.1f}\nfloor_clean_p999_us={:.1f}\nfloor_clean_max_us={:.1f}\n",
                           at(clean_us, 50), at(clean_us, 99), at(clean_us, 99.9), at(clean_us, 100))
                   .c_str(),
               stdout);
  }
  return late_us.empty() ? 1 : 0;
}
