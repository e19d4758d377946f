#pragma once
// What a process costs: resident memory now and at its peak (VmRSS, VmHWM, from /proc), and the
// CPU time it has used (all threads).

#include <sys/types.h>
#include <time.h>

#include <cstdint>
#include <fstream>
#include <string>

namespace lb::bench {

struct Memory {
  std::uint64_t rss_kib = 0;
  std::uint64_t hwm_kib = 0;
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

inline double process_cpu_s() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) / 1e9;
}

}  // namespace lb::bench
