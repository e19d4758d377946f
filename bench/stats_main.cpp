// bench-stats: figures from the latency files the bench programs write.
//   bench-stats summary FILE                    percentiles of one set
//   bench-stats overhead BRIDGE FLOOR [FLOOR2]  the bridge's latency, the floor's, and the difference
//   bench-stats memory PID                      a process and its children: rss_kib, hwm_kib, pss_kib
// A floor given as two hops (bus, DDS) is their sum for independent draws: the distribution of
// bus[i] + dds[j] over random pairs, which is what a path of both hops with nothing in between
// would show if the two hops do not influence each other.
#include <fmt/format.h>

#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "latencies.hpp"
#include "proc_stats.hpp"

namespace bench = lb::bench;

namespace {

constexpr std::size_t kFloorDraws = 1'000'000;

std::vector<std::int64_t> sum_of_hops(const std::vector<std::int64_t>& a, const std::vector<std::int64_t>& b) {
  std::mt19937_64 rng(20261101);  // fixed: the same files give the same figures
  std::uniform_int_distribution<std::size_t> pick_a(0, a.size() - 1), pick_b(0, b.size() - 1);
  std::vector<std::int64_t> sum(kFloorDraws);
  for (auto& s : sum) s = a[pick_a(rng)] + b[pick_b(rng)];
  return sum;
}

int usage() {
  std::fputs("usage: bench-stats summary FILE\n       bench-stats overhead BRIDGE_FILE FLOOR_FILE [SECOND_HOP_FILE]\n"
             "       bench-stats memory PID\n",
             stderr);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) return usage();
  const std::string cmd = argv[1];
  if (cmd == "summary" && argc == 3) {
    std::fputs(bench::format_summary("lat", bench::summarize(bench::read_latencies(argv[2]))).c_str(), stdout);
    return 0;
  }
  if (cmd == "memory" && argc == 3) {
    const auto m = bench::read_tree_memory(static_cast<pid_t>(std::stol(argv[2])));
    std::fputs(fmt::format("rss_kib={}\nhwm_kib={}\npss_kib={}\n", m.rss_kib, m.hwm_kib, m.pss_kib).c_str(), stdout);
    return 0;
  }
  if (cmd != "overhead" || argc < 4 || argc > 5) return usage();
  const auto bridge = bench::read_latencies(argv[2]);
  auto floor = bench::read_latencies(argv[3]);
  if (argc == 5) {
    const auto second = bench::read_latencies(argv[4]);
    if (floor.empty() || second.empty()) {
      std::fputs("bench-stats: an empty hop file\n", stderr);
      return 1;
    }
    floor = sum_of_hops(floor, second);
  }
  if (bridge.empty() || floor.empty()) {
    std::fputs("bench-stats: an empty latency file\n", stderr);
    return 1;
  }
  const auto b = bench::summarize(bridge);
  const auto f = bench::summarize(floor);
  std::string out = bench::format_summary("bridge", b) + bench::format_summary("floor", f);
  out += fmt::format("overhead_p50_us={:.1f}\noverhead_p99_us={:.1f}\noverhead_p999_us={:.1f}\n", b.p50_us - f.p50_us,
                     b.p99_us - f.p99_us, b.p999_us - f.p999_us);
  std::fputs(out.c_str(), stdout);
  return 0;
}
