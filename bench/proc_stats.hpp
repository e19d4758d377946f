#pragma once
// What a process costs: resident memory now and at its peak (VmRSS, VmHWM, from /proc), alone or
// with its children, and the CPU time it has used (all threads).

#include <sys/types.h>
#include <time.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <vector>

namespace lb::bench {

struct Memory {
  std::uint64_t rss_kib = 0;
  std::uint64_t hwm_kib = 0;
  std::uint64_t pss_kib = 0;  // smaps_rollup: each shared page counted once, split between its users
};

inline Memory read_memory(pid_t pid) {
  Memory m;
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("VmRSS:", 0) == 0) m.rss_kib = std::stoull(line.substr(6));
    if (line.rfind("VmHWM:", 0) == 0) m.hwm_kib = std::stoull(line.substr(6));
  }
  return m;
}

// A process's children (the split bridge's bus process: its DDS process).
inline std::vector<pid_t> children_of(pid_t pid) {
  std::vector<pid_t> pids;
  std::error_code ec;
  for (const auto& task : std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/task", ec)) {
    std::ifstream children(task.path() / "children");
    for (pid_t c = 0; children >> c;) pids.push_back(c);
  }
  return pids;
}

// A process and its children together (the split bridge: the bus process and its DDS process).
inline Memory read_tree_memory(pid_t pid) {
  std::vector<pid_t> pids{pid};
  for (const pid_t c : children_of(pid)) pids.push_back(c);
  Memory total;
  for (const pid_t p : pids) {
    const auto m = read_memory(p);
    total.rss_kib += m.rss_kib;
    total.hwm_kib += m.hwm_kib;
    std::ifstream rollup("/proc/" + std::to_string(p) + "/smaps_rollup");
    for (std::string line; std::getline(rollup, line);) {
      if (line.rfind("Pss:", 0) == 0) total.pss_kib += std::stoull(line.substr(4));
    }
  }
  return total;
}

// The CPU time another process's threads have run, in ns (each thread's schedstat: nanoseconds,
// where /proc/PID/stat counts clock ticks). Threads that have ended are not counted: for a window
// of a start-up, read while the process's threads all run.
inline std::int64_t read_cpu_ns(pid_t pid) {
  std::int64_t total = 0;
  std::error_code ec;
  for (const auto& task : std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/task", ec)) {
    std::ifstream schedstat(task.path() / "schedstat");
    std::int64_t run_ns = 0;
    if (schedstat >> run_ns) total += run_ns;
  }
  return total;
}

inline double process_cpu_s() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) / 1e9;
}

}  // namespace lb::bench
