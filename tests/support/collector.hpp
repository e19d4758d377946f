#pragma once
// Every sample of a DDS topic a test subscribes to, kept in arrival order, with a way to wait for a
// condition on them (bounded, never sleep-and-hope). The samples live in a state the reader's
// callback shares: the reader outlives the collector (it goes with its participant), and a sample
// arriving after the collector is gone must not write into freed memory.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "dds/participant.hpp"
#include "support/eventually.hpp"

namespace lb::test {

template <class PubSubType>
class Collector {
 public:
  using Sample = typename PubSubType::type;

  // keep_last deepens state topics' history so the test sees every sample, not just the latest.
  lb::Result<void> subscribe(lb::ddsl::Participant& dds, const std::string& topic, lb::ddsl::QosKind kind) {
    dds_ = &dds;
    topic_ = topic;
    return dds.subscribe<PubSubType>(
        topic, kind,
        [state = state_](const Sample& s, const lb::ddsl::fdds::SampleInfo& info) {
          {
            std::lock_guard lock(state->m);
            state->samples.push_back(s);
            const auto sn = info.sample_identity.sequence_number().to64long();
            auto [last, first] = state->last_sn.try_emplace(info.sample_identity.writer_guid(), sn);
            if (!first && sn > last->second) {
              state->gaps += sn - last->second - 1;
              last->second = sn;
            }
          }
          state->cv.notify_all();
        },
        1000);
  }

  // True once a writer (the bridge's) is matched with this reader. An event topic keeps nothing for
  // a reader that comes later: a test waits for this before it causes the event.
  bool wait_matched(std::chrono::steady_clock::duration timeout = std::chrono::seconds(30)) {
    return dds_ != nullptr && eventually(timeout, [this] { return dds_->matched_writers(topic_) > 0; });
  }

  // True when pred(samples) held within the timeout.
  bool wait(std::chrono::milliseconds timeout, const std::function<bool(const std::vector<Sample>&)>& pred) {
    std::unique_lock lock(state_->m);
    return state_->cv.wait_for(lock, timeout, [&] { return pred(state_->samples); });
  }
  bool wait_last(std::chrono::milliseconds timeout, const std::function<bool(const Sample&)>& pred) {
    return wait(timeout, [&](const std::vector<Sample>& v) { return !v.empty() && pred(v.back()); });
  }
  std::vector<Sample> samples() {
    std::lock_guard lock(state_->m);
    return state_->samples;
  }
  std::size_t size() {
    std::lock_guard lock(state_->m);
    return state_->samples.size();
  }
  // Samples a writer wrote that never arrived here: gaps in its sequence numbers between two that
  // did (a reliable keep-last writer drops what a slow reader has not acknowledged).
  std::uint64_t gaps() {
    std::lock_guard lock(state_->m);
    return state_->gaps;
  }

 private:
  struct State {
    std::mutex m;
    std::condition_variable cv;
    std::vector<Sample> samples;
    std::map<eprosima::fastrtps::rtps::GUID_t, std::uint64_t> last_sn;
    std::uint64_t gaps = 0;
  };
  std::shared_ptr<State> state_ = std::make_shared<State>();
  lb::ddsl::Participant* dds_ = nullptr;  // the participant subscribe() was given (it outlives the waits)
  std::string topic_;
};

}  // namespace lb::test
