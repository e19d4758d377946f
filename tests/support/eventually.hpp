#pragma once
// Waiting for a condition nothing notifies about (a process ended, frames on a spy): polled every
// 20 ms up to a generous deadline, so a test says what it waits for, not how long.

#include <chrono>
#include <functional>
#include <thread>

namespace lb::test {

inline bool eventually(std::chrono::steady_clock::duration timeout, const std::function<bool()>& cond) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!cond()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

}  // namespace lb::test
