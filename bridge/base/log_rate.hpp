#pragma once
// Bounds how often one kind of message is logged: a device that floods the bus with EMCYs or
// malformed frames must not flood the log (and the disk, and journald) with a line per frame.
// The first `burst` messages of every second get through; the rest are counted, and the next
// one that gets through says how many were held back. Not thread-safe: one per thread's site.

#include <chrono>
#include <cstdint>
#include <string>

#include <fmt/format.h>

namespace lb {

class LogRate {
 public:
  explicit LogRate(unsigned burst_per_second = 5) : burst_(burst_per_second) {}

  // True: log this one; held_back() then says how many since the last one that got through.
  bool allow(std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now()) {
    if (now - window_start_ >= std::chrono::seconds(1)) {
      window_start_ = now;
      in_window_ = 0;
    }
    if (in_window_ < burst_) {
      ++in_window_;
      last_held_back_ = held_back_;
      held_back_ = 0;
      return true;
    }
    ++held_back_;
    return false;
  }
  // Messages not logged before the one allow() just let through.
  std::uint64_t held_back() const { return last_held_back_; }

 private:
  unsigned burst_;
  unsigned in_window_ = 0;
  std::chrono::steady_clock::time_point window_start_{};
  std::uint64_t held_back_ = 0;
  std::uint64_t last_held_back_ = 0;
};

// What to append to a message that allow() let through: " (N more not logged)", or nothing.
inline std::string held_back_note(const LogRate& rate) {
  return rate.held_back() == 0 ? std::string() : fmt::format(" ({} more not logged)", rate.held_back());
}

}  // namespace lb
