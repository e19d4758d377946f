#pragma once
// Every sample of a DDS topic a test subscribes to, kept in arrival order, with a way to wait for a
// condition on them (bounded, never sleep-and-hope).

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "dds/participant.hpp"

namespace lb::test {

template <class PubSubType>
class Collector {
 public:
  using Sample = typename PubSubType::type;

  // keep_last deepens state topics' history so the test sees every sample, not just the latest.
  lb::Result<void> subscribe(lb::ddsl::Participant& dds, const std::string& topic, lb::ddsl::QosKind kind) {
    return dds.subscribe<PubSubType>(
        topic, kind,
        [this](const Sample& s, const lb::ddsl::fdds::SampleInfo&) {
          {
            std::lock_guard lock(m_);
            samples_.push_back(s);
          }
          cv_.notify_all();
        },
        1000);
  }

  // True when pred(samples) held within the timeout.
  bool wait(std::chrono::milliseconds timeout, const std::function<bool(const std::vector<Sample>&)>& pred) {
    std::unique_lock lock(m_);
    return cv_.wait_for(lock, timeout, [&] { return pred(samples_); });
  }
  bool wait_last(std::chrono::milliseconds timeout, const std::function<bool(const Sample&)>& pred) {
    return wait(timeout, [&](const std::vector<Sample>& v) { return !v.empty() && pred(v.back()); });
  }
  std::vector<Sample> samples() {
    std::lock_guard lock(m_);
    return samples_;
  }
  std::size_t size() {
    std::lock_guard lock(m_);
    return samples_.size();
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::vector<Sample> samples_;
};

}  // namespace lb::test
