// bench-can-sink: the bare bus hop. A member of one virtual bus that times every stamped saw
// TPDO from its send time to the moment receive() hands it over: the part of the bridge's
// CAN -> DDS latency that the bus costs by itself.
#include <poll.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <vector>

#include "can/bus.hpp"
#include "clock.hpp"
#include "latencies.hpp"
#include "proc_stats.hpp"
#include "program.hpp"
#include "saw_stamps.hpp"

namespace bench = lb::bench;

int main(int argc, char** argv) {
  bench::Program program{"bench-can-sink", "latency of the bare virtual-bus hop"};
  auto& cli = program.cli;
  int bus_index = 0;
  std::uint64_t expect = 10000;
  std::uint64_t warmup = 0;
  double idle_s = 3;
  program.add_prefix();
  cli.add_option("--bus", bus_index)->capture_default_str();
  cli.add_option("--expect", expect, "stamped frames to receive, warm-up included")->capture_default_str();
  cli.add_option("--warmup", warmup, "first frames left out of the figures")->capture_default_str();
  cli.add_option("--idle", idle_s, "give up after this long without a frame, seconds")->capture_default_str();
  program.add_out();
  program.add_ready("the bus is open");
  if (auto rc = program.parse(argc, argv)) return *rc;

  auto bus = lb::can::open_bus(bench::bus_uri(program.prefix, bus_index));
  if (!bus) return program.fail(bus.error().message);
  program.ready();

  std::vector<std::int64_t> latencies;
  latencies.reserve(expect);
  std::uint64_t received = 0, errors = 0;
  const int idle_ms = static_cast<int>(idle_s * 1000);
  bool started = false;
  double cpu0 = 0;
  std::int64_t first_ns = 0, last_ns = 0;
  while (received < expect) {
    pollfd p{(*bus)->fd(), POLLIN, 0};
    // Before the first frame the injector may still be waiting for its go: wait longer.
    const int r = ::poll(&p, 1, started ? idle_ms : 10 * idle_ms);
    if (r == 0) break;
    if (r < 0) continue;
    for (;;) {
      auto frame = (*bus)->receive();
      if (!frame || !frame->has_value()) break;
      const auto now = bench::realtime_ns();
      if ((*frame)->error) {
        ++errors;  // the hub's overflow notice: frames were lost
        continue;
      }
      const auto stamp = bench::frame_stamp(**frame);
      if (!stamp) continue;
      if (!started) {
        started = true;
        cpu0 = bench::process_cpu_s();
        first_ns = now;
      }
      last_ns = now;
      if (received++ >= warmup) latencies.push_back(bench::elapsed_since(*stamp, now));
    }
  }
  program.save_latencies(latencies);
  const double busy_s = static_cast<double>(last_ns - first_ns) / 1e9;
  std::printf("sink_frames=%llu\nsink_error_frames=%llu\nsink_cpu_pct=%.1f\n",
              static_cast<unsigned long long>(received), static_cast<unsigned long long>(errors),
              busy_s > 0 ? 100 * (bench::process_cpu_s() - cpu0) / busy_s : 0.0);
  std::fputs(bench::format_summary("bus_hop", bench::summarize(latencies)).c_str(), stdout);
  return received == expect && errors == 0 ? 0 : 3;
}
