#pragma once
// The master's check that a device runs the set value it was sent (profile-decisions.md, "Master
// role"): the set echo (6004h) is compared with the set value (6002h) at every echo sample. A
// difference within the settling time is the device catching up (the RPDO takes effect at the next
// SYNC); only one lasting longer than that is flagged, and the first agreeing sample clears it.

#include <cstdint>
#include <cstdlib>

namespace lb::gateways {

class SetEchoMonitor {
 public:
  struct Settings {
    unsigned settle_samples = 3;  // echo samples (one per SYNC with transmission type 1)
    std::int64_t tolerance = 1;   // raw units
  };

  SetEchoMonitor() = default;
  explicit SetEchoMonitor(Settings settings) : settings_(settings) {}

  // Raw, sign-extended values; returns whether the difference is now a lasting one.
  bool observe(std::int64_t set, std::int64_t echo) {
    if (set != last_set_) {
      // A new set value starts a new settling time: the device gets it at the next SYNC.
      last_set_ = set;
      restart();
    }
    if (std::llabs(set - echo) <= settings_.tolerance) {
      streak_ = 0;
      mismatch_ = false;
    } else if (++streak_ > settings_.settle_samples) {
      mismatch_ = true;
    }
    return mismatch_;
  }
  bool mismatch() const { return mismatch_; }
  // The master sent a new set value: the device gets a new settling time from now on.
  void restart() {
    streak_ = 0;
    mismatch_ = false;
  }

 private:
  Settings settings_;
  std::int64_t last_set_ = 0;
  unsigned streak_ = 0;
  bool mismatch_ = false;
};

}  // namespace lb::gateways
