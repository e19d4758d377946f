#pragma once
// Requests and set values a client wrote that never reached the bridge's callback. Fast DDS drops
// them without a word: a reliable keep-last writer overwrites what its reader has not acknowledged
// yet (a client writing faster than the bridge reads), and a keep-last reader overwrites what was
// not taken. Each writer numbers its samples, so a gap between two that arrive is what was lost.
// Counted for the diagnostics and logged at a bounded rate, so "no answer" has a cause on record.

#include <atomic>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>

#include <fastdds/dds/subscriber/SampleInfo.hpp>

#include "base/log_rate.hpp"
#include "link/pi_mutex.hpp"

namespace lb::ddsl {

class LostSamples {
 public:
  // Any Fast DDS thread (or bus loop, for a reader on a lane), for every sample taken from a
  // command reader.
  void seen(const eprosima::fastrtps::rtps::SampleIdentity& id, const std::string& topic);
  std::uint64_t lost() const { return lost_.load(std::memory_order_relaxed); }

 private:
  // Writers come and go (every CLI call has its own); past this many the record starts afresh,
  // which can only miss a gap, never invent one.
  static constexpr std::size_t kMaxWriters = 1024;

  link::PiMutex mutex_;  // a realtime bus loop may wait on it (lanes): priority inheritance
  std::map<eprosima::fastrtps::rtps::GUID_t, std::uint64_t> last_;
  LogRate log_{2};
  std::atomic<std::uint64_t> lost_{0};
};

}  // namespace lb::ddsl
