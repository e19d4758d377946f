#pragma once
// What bench-channel-hop and bench-iceoryx-hop share, so that the two mechanisms are run, timed and
// reported alike: the ping-pong's options (--count, --warmup, --interval-us), the hop_<key>_{p50,p99,p999,max}_us lines
// (percentile: the sample at index floor(q * n) of the sorted set, as these two programs have always reported it), and
// the last `count` samples kept (the start-up samples before the first echo are timed too).

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <vector>

namespace lb::bench {

struct HopRun {
  std::uint64_t count = 20000;  // timed samples
  std::uint64_t warmup = 500;   // sent first, not timed
  int interval_us = 500;        // between one echo and the next sample

  void add(CLI::App& cli) {
    cli.add_option("--count", count, "timed samples")->capture_default_str();
    cli.add_option("--warmup", warmup, "samples first, not timed")->capture_default_str();
    cli.add_option("--interval-us", interval_us, "pause between one echo and the next sample")->capture_default_str();
  }
  std::uint64_t total() const { return count + warmup; }
};

inline void print_hop(const char* key, std::vector<std::int64_t> v) {
  std::sort(v.begin(), v.end());
  auto at = [&](double q) {
    if (v.empty()) return 0.0;
    return static_cast<double>(v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))]) /
           1000.0;
  };
  const double max = v.empty() ? 0.0 : static_cast<double>(v.back()) / 1000.0;
  std::printf("hop_%s_p50_us=%.1f\nhop_%s_p99_us=%.1f\nhop_%s_p999_us=%.1f\nhop_%s_max_us=%.1f\n", key, at(0.50), key,
              at(0.99), key, at(0.999), key, max);
}

inline void keep_last(std::vector<std::int64_t>& v, std::uint64_t count) {
  if (v.size() > count) v.erase(v.begin(), v.end() - static_cast<std::ptrdiff_t>(count));
}

}  // namespace lb::bench
