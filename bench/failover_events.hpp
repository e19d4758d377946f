#pragma once
// How the processes of bench-ownership-failover tell its conductor what happened and when: one
// line per event ("<kind> <tag> <seq> <monotonic ns>") written with one write() to a pipe they all
// share (fd 3; a line below PIPE_BUF arrives whole, never mixed with another process's), and the
// conductor's log of them, read on its own thread, that it waits on. Not stdout: Fast DDS may
// print there. CLOCK_MONOTONIC is one clock for every process of the machine, so times from
// different processes subtract.

#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "clock.hpp"

namespace lb::bench {

constexpr int kEventsFd = 3;

// Event kinds. The reader's: a sample taken by its EXCLUSIVE reader ('x') or by its default
// (SHARED) reader ('s'), a writer's liveliness lost ('l') or the writer unmatched ('u') at the
// EXCLUSIVE reader, each under the writer's tag; a writer's participant discovered ('p'). Every
// process's: ready ('r').
// The standby's: it saw the master's process end ('d'), it created its writer ('c').
inline void emit(char kind, std::uint32_t tag, std::uint64_t seq) {
  char line[96];
  const int n = std::snprintf(line, sizeof line, "%c %u %llu %lld\n", kind, tag, static_cast<unsigned long long>(seq),
                              static_cast<long long>(monotonic_ns()));
  if (n <= 0) return;
  // Lost only if the conductor is gone: then nobody waits for it.
  if (::write(kEventsFd, line, static_cast<std::size_t>(n)) < 0) return;
}

// What one process (by its tag) was seen doing, times in monotonic ns.
struct Heard {
  std::vector<std::int64_t> exclusive;  // samples its writer got into the EXCLUSIVE reader
  std::vector<std::int64_t> shared;     // ... into the default (SHARED) reader
  std::vector<std::int64_t> lost;       // the EXCLUSIVE reader found its liveliness lost
  std::vector<std::int64_t> unmatched;  // ... unmatched it
  std::int64_t ready = -1, discovered = -1, saw_death = -1, created = -1;
};

class EventLog {
 public:
  // Reads fd (the pipe's read end) until every write end is closed.
  explicit EventLog(int fd) : fd_(fd), thread_([this] { run(); }) {}
  ~EventLog() {
    if (thread_.joinable()) thread_.join();
  }
  EventLog(const EventLog&) = delete;
  EventLog& operator=(const EventLog&) = delete;

  // Waits until pred(the log) holds or timeout passes; the log is locked while pred runs.
  bool wait(std::chrono::milliseconds timeout, const std::function<bool(const std::map<std::uint32_t, Heard>&)>& pred) {
    std::unique_lock lock(mutex_);
    return changed_.wait_for(lock, timeout, [&] { return pred(heard_); });
  }
  template <class F>
  auto read(F&& f) {
    std::lock_guard lock(mutex_);
    return f(heard_);
  }

 private:
  void run() {
    std::string pending;
    char buf[4096];
    for (;;) {
      const auto n = ::read(fd_, buf, sizeof buf);
      if (n <= 0) return;
      pending.append(buf, static_cast<std::size_t>(n));
      std::size_t start = 0;
      for (auto end = pending.find('\n'); end != std::string::npos; end = pending.find('\n', start)) {
        take(pending.substr(start, end - start));
        start = end + 1;
      }
      pending.erase(0, start);
    }
  }
  void take(const std::string& line) {
    std::istringstream in(line);
    char kind = 0;
    std::uint32_t tag = 0;
    std::uint64_t seq = 0;
    std::int64_t t = 0;
    if (!(in >> kind >> tag >> seq >> t)) return;
    {
      std::lock_guard lock(mutex_);
      auto& h = heard_[tag];
      switch (kind) {
        case 'x': h.exclusive.push_back(t); break;
        case 's': h.shared.push_back(t); break;
        case 'p': h.discovered = t; break;
        case 'l': h.lost.push_back(t); break;
        case 'u': h.unmatched.push_back(t); break;
        case 'r': h.ready = t; break;
        case 'd': h.saw_death = t; break;
        case 'c': h.created = t; break;
        default: return;
      }
    }
    changed_.notify_all();
  }

  int fd_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::map<std::uint32_t, Heard> heard_;
  std::thread thread_;  // last: starts once the members it uses exist
};

}  // namespace lb::bench
