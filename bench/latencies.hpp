#pragma once
// A set of latencies in nanoseconds: collected by a measuring program, written one per line (so a
// run can be re-analysed), and summarised as the percentiles the bench table reports.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>

namespace lb::bench {

struct Summary {
  std::size_t n = 0;
  double p50_us = 0, p99_us = 0, p999_us = 0, max_us = 0, mean_us = 0;
};

// Nearest-rank percentile of sorted values.
inline std::int64_t percentile(const std::vector<std::int64_t>& sorted, double p) {
  if (sorted.empty()) return 0;
  const auto rank = static_cast<std::size_t>(std::ceil(p * static_cast<double>(sorted.size())));
  return sorted[std::clamp<std::size_t>(rank, 1, sorted.size()) - 1];
}

inline Summary summarize(std::vector<std::int64_t> ns) {
  Summary s;
  s.n = ns.size();
  if (ns.empty()) return s;
  std::sort(ns.begin(), ns.end());
  double sum = 0;
  for (auto v : ns) sum += static_cast<double>(v);
  s.p50_us = static_cast<double>(percentile(ns, 0.50)) / 1e3;
  s.p99_us = static_cast<double>(percentile(ns, 0.99)) / 1e3;
  s.p999_us = static_cast<double>(percentile(ns, 0.999)) / 1e3;
  s.max_us = static_cast<double>(ns.back()) / 1e3;
  s.mean_us = sum / static_cast<double>(ns.size()) / 1e3;
  return s;
}

// key=value lines, the format every bench program reports in (prefix names the set).
inline std::string format_summary(const std::string& prefix, const Summary& s) {
  return fmt::format("{0}_n={1}\n{0}_p50_us={2:.1f}\n{0}_p99_us={3:.1f}\n{0}_p999_us={4:.1f}\n{0}_max_us={5:.1f}\n"
                     "{0}_mean_us={6:.1f}\n",
                     prefix, s.n, s.p50_us, s.p99_us, s.p999_us, s.max_us, s.mean_us);
}

inline bool write_latencies(const std::string& path, const std::vector<std::int64_t>& ns) {
  std::ofstream out(path);
  for (auto v : ns) out << v << '\n';
  return static_cast<bool>(out);
}

inline std::vector<std::int64_t> read_latencies(const std::string& path) {
  std::vector<std::int64_t> ns;
  std::ifstream in(path);
  for (std::int64_t v = 0; in >> v;) ns.push_back(v);
  return ns;
}

}  // namespace lb::bench
