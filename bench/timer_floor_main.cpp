// bench-timer-floor: the floor under the SYNC jitter figure. A bare periodic timer (absolute
// clock_nanosleep, as cyclictest does), run where the bridge runs: how late the machine wakes a
// thread that does nothing else. No program's SYNC can be steadier than this on the same core.
// With --sentinel-cpu, also over the wake-ups no host stall touched (stall_sentinel.hpp): how
// steady the core is between the host's stalls.
#include <fmt/format.h>
#include <time.h>
#include <CLI/CLI.hpp>

#include <cstdint>
#include <cstdio>
#include <optional>
#include <vector>

#include "clock.hpp"
#include "latencies.hpp"
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
  std::vector<std::int64_t> late_ns;
  std::vector<std::int64_t> woke_at;  // CLOCK_REALTIME, the sentinel's clock
  late_ns.reserve(n);
  woke_at.reserve(n);
  std::optional<bench::StallSentinel> sentinel;
  if (!sentinel_options.start(sentinel, "bench-timer-floor")) return 1;
  std::int64_t due = bench::monotonic_ns();
  for (std::size_t i = 0; i < n; ++i) {
    due += period_ns;
    const timespec at{static_cast<time_t>(due / 1'000'000'000), static_cast<long>(due % 1'000'000'000)};
    ::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, nullptr);
    late_ns.push_back(bench::monotonic_ns() - due);
    woke_at.push_back(bench::realtime_ns());
  }
  const auto all = bench::summarize(late_ns);
  std::fputs(
      fmt::format(
          "floor_wakeups={}\nfloor_p50_us={:.1f}\nfloor_p99_us={:.1f}\nfloor_p999_us={:.1f}\nfloor_max_us={:.1f}\n",
          all.n, all.p50_us, all.p99_us, all.p999_us, all.max_us)
          .c_str(),
      stdout);
  if (sentinel) {
    const auto& stalls = sentinel->stop();
    std::vector<std::int64_t> clean_ns;
    for (std::size_t i = 0; i < late_ns.size(); ++i) {
      if (!bench::stalled(stalls, woke_at[i], sentinel_options.window_ns())) clean_ns.push_back(late_ns[i]);
    }
    std::fputs(fmt::format("floor_host_stalls={}\n{}", stalls.size(),
                           bench::format_summary("floor_clean", bench::summarize(clean_ns)))
                   .c_str(),
               stdout);
  }
  return late_ns.empty() ? 1 : 0;
}
