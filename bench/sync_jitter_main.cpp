// bench-sync-jitter: a member of one virtual bus that measures the SYNC a master produces there:
// every SYNC frame's bus time (its frame stamp: when the master sent it), the periods between them,
// and how far each period is from the nominal one; the same from the times this meter read them. Optionally it is also
// a device that floods the bus with EMCYs (an EMCY burst, as a device with a loose contact sends them), so that the
// bridge has events to publish while a reader of them is frozen, and a source of hostile frames (any identifier, 11 or
// 29 bits, any length, remote requests, random data). With --sentinel-cpu, a host-stall sentinel (stall_sentinel.hpp)
// runs on the bridge's core meanwhile, and the figures come twice: over every period, and over the
// periods whose SYNCs no host stall touched. Prints key=value lines; the periods go to --out.
#include <fmt/format.h>
#include <poll.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <optional>
#include <vector>

#include "can/bus.hpp"
#include "clock.hpp"
#include "latencies.hpp"
#include "names.hpp"
#include "stall_sentinel.hpp"

namespace bench = lb::bench;

int main(int argc, char** argv) {
  CLI::App cli{"bench-sync-jitter: SYNC period jitter on a virtual bus, with an optional EMCY burst"};
  std::string uri;
  double duration_s = 20;
  double period_us = 20000;
  double emcy_rate = 0;
  int emcy_devices = 30;
  double hostile_rate = 0;
  std::string out;
  bench::SentinelOptions sentinel_options;
  cli.add_option("--bus", uri, "virtual:<name>")->required();
  cli.add_option("--hostile-rate", hostile_rate, "random frames per second (0: none)")->capture_default_str();
  cli.add_option("--duration", duration_s, "seconds to measure")->check(CLI::Range(1.0, 7200.0))->capture_default_str();
  cli.add_option("--period-us", period_us, "the nominal SYNC period")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cli.add_option("--emcy-rate", emcy_rate, "EMCY frames per second, spread over the devices (0: none)")
      ->capture_default_str();
  cli.add_option("--emcy-devices", emcy_devices, "devices (bench node-IDs) the EMCYs come from")
      ->check(CLI::Range(1, bench::kMaxDevicesPerBus))
      ->capture_default_str();
  cli.add_option("--out", out,
                 "file for the periods: one per line, its length (us), 1 if a host stall touched it (else 0), its "
                 "closing SYNC's stamp (ns, CLOCK_REALTIME)");
  sentinel_options.add_to(cli, "the bridge");
  CLI11_PARSE(cli, argc, argv);

  auto bus = lb::can::open_bus(uri);
  if (!bus) {
    std::fprintf(stderr, "bench-sync-jitter: %s\n", bus.error().message.c_str());
    return 1;
  }
  // Two clocks per SYNC: its frame stamp (when it went on the bus: the bridge's send) and when this
  // meter read it (adds the hub's and the meter's own scheduling on a loaded machine).
  std::vector<std::int64_t> syncs, read_at;
  syncs.reserve(static_cast<std::size_t>(duration_s * 1e6 / period_us * 1.2) + 16);
  read_at.reserve(syncs.capacity());
  std::optional<bench::StallSentinel> sentinel;
  if (!sentinel_options.start(sentinel, "bench-sync-jitter")) return 1;
  const auto start = bench::monotonic_ns();
  const auto end = start + static_cast<std::int64_t>(duration_s * 1e9);
  const double emcy_period_ns = emcy_rate > 0 ? 1e9 / emcy_rate : 0;
  std::uint64_t emcy_sent = 0, emcy_dropped = 0;
  const double hostile_period_ns = hostile_rate > 0 ? 1e9 / hostile_rate : 0;
  std::uint64_t hostile_sent = 0, hostile_dropped = 0;
  std::uint64_t rng = 0x9E3779B97F4A7C15ULL;
  const auto next = [&rng] {  // xorshift64: reproducible, no state outside this run
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return rng;
  };
  for (auto now = start; now < end; now = bench::monotonic_ns()) {
    // EMCYs due by now (alternating error and reset, so every one is news to a subscriber).
    if (emcy_rate > 0) {
      const auto due = static_cast<std::uint64_t>(static_cast<double>(now - start) / emcy_period_ns);
      for (; emcy_sent + emcy_dropped < due;) {
        const auto k = emcy_sent + emcy_dropped;
        const auto node = bench::node_id(static_cast<int>(k % static_cast<std::uint64_t>(emcy_devices)));
        const bool error = (k / static_cast<std::uint64_t>(emcy_devices)) % 2 == 0;
        const auto f = lb::can::make_frame(0x080 + node,
                                           {static_cast<std::uint8_t>(error ? 0x10 : 0x00),
                                            static_cast<std::uint8_t>(error ? 0x42 : 0x00),
                                            static_cast<std::uint8_t>(error ? 0x09 : 0x00), 0, 0, 0, 0, 0});
        if ((*bus)->send(f))
          ++emcy_sent;
        else
          ++emcy_dropped;
      }
    }
    if (hostile_rate > 0) {
      const auto due = static_cast<std::uint64_t>(static_cast<double>(now - start) / hostile_period_ns);
      for (; hostile_sent + hostile_dropped < due;) {
        const auto r = next();
        lb::can::CanFrame f;
        f.extended = (r & 0xF) == 0;
        f.rtr = ((r >> 4) & 0x1F) == 0;
        f.id = static_cast<std::uint32_t>(r >> 16) & (f.extended ? 0x1FFF'FFFFU : 0x7FFU);
        f.len = static_cast<std::uint8_t>((r >> 8) % 9);
        const auto data = next();
        for (std::size_t i = 0; i < 8; ++i) f.data[i] = static_cast<std::uint8_t>(data >> (8 * i));
        if ((*bus)->send(f))
          ++hostile_sent;
        else
          ++hostile_dropped;
      }
    }
    pollfd p{(*bus)->fd(), POLLIN, 0};
    const int wait_ms = emcy_rate > 0 || hostile_rate > 0 ? 1 : 10;
    if (::poll(&p, 1, wait_ms) <= 0) continue;
    for (;;) {
      auto r = (*bus)->receive();
      if (!r || !r->has_value()) break;
      const auto& f = **r;
      if (f.id == 0x080 && !f.extended && !f.rtr && !f.error) {
        syncs.push_back(f.timestamp_ns);
        read_at.push_back(bench::realtime_ns());
      }
    }
  }
  const std::vector<bench::HostStall> no_stalls;
  const auto& stalls = sentinel ? sentinel->stop() : no_stalls;
  const auto window_ns = sentinel_options.window_ns();
  const auto nominal_ns = static_cast<std::int64_t>(period_us * 1e3);
  std::vector<std::int64_t> deviation_ns, read_deviation_ns, clean_deviation_ns;
  std::int64_t longest_period_ns = 0;
  std::ofstream periods_file;
  if (!out.empty()) periods_file.open(out);
  for (std::size_t i = 1; i < syncs.size(); ++i) {
    const std::int64_t period_ns = syncs[i] - syncs[i - 1];
    longest_period_ns = std::max(longest_period_ns, period_ns);
    deviation_ns.push_back(std::abs(period_ns - nominal_ns));
    read_deviation_ns.push_back(std::abs(read_at[i] - read_at[i - 1] - nominal_ns));
    // A period is as late as its end and as early as its start is late: a stall at either SYNC counts.
    const bool touched = bench::stalled(stalls, syncs[i - 1], window_ns) || bench::stalled(stalls, syncs[i], window_ns);
    if (!touched) clean_deviation_ns.push_back(deviation_ns.back());
    if (periods_file)
      periods_file << fmt::format("{:.1f} {} {}\n", static_cast<double>(period_ns) / 1e3, touched ? 1 : 0, syncs[i]);
  }
  if (sentinel) {
    std::int64_t stalled_ns = 0, longest_stall_ns = 0;
    for (const auto& st : stalls) {
      stalled_ns += st.end_ns - st.begin_ns;
      longest_stall_ns = std::max(longest_stall_ns, st.end_ns - st.begin_ns);
    }
    std::fputs(
        fmt::format("jitter_host_stalls={}\njitter_host_stalled_ms={:.1f}\njitter_host_longest_stall_us={:.1f}\n{}",
                    stalls.size(), static_cast<double>(stalled_ns) / 1e6, static_cast<double>(longest_stall_ns) / 1e3,
                    bench::format_summary("jitter_clean", bench::summarize(clean_deviation_ns)))
            .c_str(),
        stdout);
  }
  const double expected = duration_s * 1e6 / period_us;
  std::fputs(fmt::format("jitter_syncs={}\njitter_expected_syncs={:.0f}\njitter_longest_period_us={:.1f}\n"
                         "jitter_emcy_sent={}\njitter_emcy_dropped={}\njitter_hostile_sent={}\n{}{}",
                         syncs.size(), expected, static_cast<double>(longest_period_ns) / 1e3, emcy_sent, emcy_dropped,
                         hostile_sent, bench::format_summary("jitter", bench::summarize(deviation_ns)),
                         bench::format_summary("jitter_read", bench::summarize(read_deviation_ns)))
                 .c_str(),
             stdout);
  return syncs.size() < 2 ? 1 : 0;
}
