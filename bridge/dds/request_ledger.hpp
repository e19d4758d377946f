#pragma once
// The requests a service server took lately and what it answered, so that a request asked again
// (its answer lost on the way: Fast DDS 2.9.1 can lose a writer's last sample after a burst, see
// README "Requests written faster than read") gets its first answer instead of a second run: a
// second manual cut, a second NMT reset or SDO write must not follow from a lost answer.
//
// A client asks again by writing the same request from the same writer with the first request's
// sample identity as its related sample identity (RequestLedger::asked_as). Bounded: the last
// kCapacity requests of the last kKeep; a repeat of an older one is taken as a new request.

#include <chrono>
#include <deque>
#include <map>
#include <mutex>
#include <optional>

#include <fastdds/dds/subscriber/SampleInfo.hpp>
#include <fastdds/rtps/common/SampleIdentity.h>

namespace lb::ddsl {

template <class Reply>
class RequestLedger {
 public:
  using SampleIdentity = eprosima::fastrtps::rtps::SampleIdentity;
  using Clock = std::chrono::steady_clock;
  static constexpr std::size_t kCapacity = 256;
  static constexpr std::chrono::seconds kKeep{60};

  enum class Seen { first, in_progress, answered };
  struct Admission {
    Seen seen;
    std::optional<Reply> answer;  // set when seen == answered
  };

  // The request a sample asks: an earlier one of the same writer that it repeats, or itself. A
  // repeat can name only its own writer's requests: no client can draw another client's answers
  // or stop another client's request from running.
  static SampleIdentity asked_as(const eprosima::fastdds::dds::SampleInfo& info) {
    const SampleIdentity& first = info.related_sample_identity;
    const SampleIdentity& self = info.sample_identity;
    const bool repeat = first != SampleIdentity::unknown() && first.writer_guid() == self.writer_guid() &&
                        first.sequence_number() < self.sequence_number();
    return repeat ? first : self;
  }

  // Called for every request taken: the first time, it is recorded as in progress and must be run.
  Admission admit(const SampleIdentity& request, Clock::time_point now = Clock::now()) {
    std::lock_guard lock(mutex_);
    forget_old(now);
    if (auto it = entries_.find(request); it != entries_.end()) {
      if (!it->second) return {Seen::in_progress, std::nullopt};
      return {Seen::answered, it->second};
    }
    entries_.emplace(request, std::nullopt);
    order_.push_back({now, request});
    return {Seen::first, std::nullopt};
  }

  // Keeps the first answer (a handler answering twice is harmless: the repeat gets the first).
  void answered(const SampleIdentity& request, const Reply& reply) {
    std::lock_guard lock(mutex_);
    if (auto it = entries_.find(request); it != entries_.end() && !it->second) it->second = reply;
  }

  std::size_t size() const {
    std::lock_guard lock(mutex_);
    return entries_.size();
  }

 private:
  void forget_old(Clock::time_point now) {
    while (!order_.empty() && (order_.size() >= kCapacity || now - order_.front().first > kKeep)) {
      entries_.erase(order_.front().second);
      order_.pop_front();
    }
  }

  mutable std::mutex mutex_;
  std::map<SampleIdentity, std::optional<Reply>> entries_;  // nullopt: in progress
  std::deque<std::pair<Clock::time_point, SampleIdentity>> order_;
};

}  // namespace lb::ddsl
