#pragma once
// Bounds how often the same message is logged: a device that stays absent, or a boot that keeps
// failing the same way, must not write the same lines every few seconds for ever (the log goes to
// journald and the disk). A message that differs from the last one always gets through; the same
// one again at most once per interval, saying how many were held back. Not thread-safe: one per
// thread's site.

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>

#include <fmt/format.h>

namespace lb {

class RepeatLog {
 public:
  explicit RepeatLog(std::chrono::seconds interval = std::chrono::seconds(60)) : interval_(interval) {}

  // True: log this one; note() then says how many of it were held back before.
  bool allow(std::string_view text, std::chrono::steady_clock::time_point now = std::chrono::steady_clock::now()) {
    if (text != last_ || now - logged_at_ >= interval_) {
      held_ = text == last_ ? held_back_ : 0;
      last_ = text;
      logged_at_ = now;
      held_back_ = 0;
      return true;
    }
    ++held_back_;
    return false;
  }
  std::string note() const {
    return held_ == 0 ? std::string() : fmt::format(" (the same {} more time(s) since, not logged)", held_);
  }

 private:
  std::chrono::seconds interval_;
  std::string last_;
  std::chrono::steady_clock::time_point logged_at_{};
  std::uint64_t held_back_ = 0;
  std::uint64_t held_ = 0;
};

}  // namespace lb
