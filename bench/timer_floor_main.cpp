// bench-timer-floor: the floor under the SYNC jitter figure. A bare periodic timer (absolute
// clock_nanosleep, as cyclictest does), run where the bridge runs: how late the machine wakes a
// thread that does nothing else. No program's SYNC can be steadier than this on the same core.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include "clock.hpp"

namespace bench = lb::bench;

int main(int argc, char** argv) {
  CLI::App cli{"bench-timer-floor: wake-up lateness of a bare periodic timer"};
  double duration_s = 60;
  double period_us = 20000;
  cli.add_option("--duration", duration_s, "seconds to measure")->check(CLI::Range(1.0, 7200.0))->capture_default_str();
  cli.add_option("--period-us", period_us, "the timer's period")->check(CLI::Range(100.0, 1e6))->capture_default_str();
  CLI11_PARSE(cli, argc, argv);

  const auto period_ns = static_cast<std::int64_t>(period_us * 1e3);
  const auto n = static_cast<std::size_t>(duration_s * 1e9 / static_cast<double>(period_ns));
  std::vector<double> late_us;
  late_us.reserve(n);
  std::int64_t due = bench::monotonic_ns();
  for (std::size_t i = 0; i < n; ++i) {
    due += period_ns;
    const timespec at{static_cast<time_t>(due / 1'000'000'000), static_cast<long>(due % 1'000'000'000)};
    ::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, nullptr);
    late_us.push_back(static_cast<double>(bench::monotonic_ns() - due) / 1e3);
  }
  std::sort(late_us.begin(), late_us.end());
  const auto at = [&](double p) {
    const auto i = static_cast<std::size_t>(std::ceil(p / 100.0 * static_cast<double>(late_us.size()))) - 1;
    return late_us[std::min(i, late_us.size() - 1)];
  };
  std::fputs(fmt::format("floor_wakeups={}\nfloor_p50_us={:.1f}\nfloor_p99_us={:.1f}\nfloor_p999_us={:.1f}\nfloor_max_us={:.1f}\n",
                         late_us.size(), at(50), at(99), at(99.9), late_us.back())
                 .c_str(),
             stdout);
  return late_us.empty() ? 1 : 0;
}
