#pragma once
// A LogRate for a site that several threads reach: a device's set values are refused on the DDS
// threads that take them and on its bus loop, and an application writing them as fast as it can
// (the request flood of bench.sh's soak: ~47,000 refusals a second) must not write the log that fast.

#include <mutex>
#include <optional>
#include <string>

#include "base/log_rate.hpp"

namespace lb {

class SharedLogRate {
 public:
  explicit SharedLogRate(unsigned burst_per_second = 5) : rate_(burst_per_second) {}

  // Empty: do not log this one. Otherwise what to append to the message: how many were held back
  // before it ("" when none).
  std::optional<std::string> allow() {
    std::lock_guard lock(mutex_);
    if (!rate_.allow()) return std::nullopt;
    return held_back_note(rate_);
  }

 private:
  std::mutex mutex_;
  LogRate rate_;
};

}  // namespace lb
