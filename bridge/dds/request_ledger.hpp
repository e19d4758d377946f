#pragma once
// The requests a service server took lately and what it answered, so that a request asked again
// (its answer lost on the way: Fast DDS 2.9.1 can lose a writer's last sample after a burst, see
// README "Requests written faster than read") gets its first answer instead of a second run: a
// second manual cut, a second NMT reset or SDO write must not follow from a lost answer.
//
// A client asks again by writing the same request from the same writer with the first request's
// sample identity as its related sample identity (RequestLedger::asked_as). A repeat must carry
// the same content as the request it names (compared by a fingerprint of the request): one that
// differs is refused, never answered with another request's result.
//
// Bounded, and a request still running is never forgotten (forgetting it would let its repeat run
// it a second time): at most kMaxInProgress requests run at once, and a new request beyond that
// is refused (busy) instead of pushing another out. Answered requests are kept kKeep after their
// answer, the last kCapacity of them; a repeat of an older one is taken as a new request.

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>

#include <fastdds/rtps/common/SampleIdentity.h>
#include <fastdds/dds/subscriber/SampleInfo.hpp>

namespace lb::ddsl {

template <class Reply>
class RequestLedger {
 public:
  using SampleIdentity = eprosima::fastrtps::rtps::SampleIdentity;
  using Clock = std::chrono::steady_clock;
  // What a request asks, reduced to a number (service.hpp: a hash of its serialized form). Equal
  // contents give equal fingerprints; a repeat whose fingerprint differs is not the same request.
  using Fingerprint = std::uint64_t;
  static constexpr std::size_t kCapacity = 256;       // answered requests kept
  static constexpr std::size_t kMaxInProgress = 256;  // requests running at once
  static constexpr std::chrono::seconds kKeep{60};

  enum class Seen {
    first,        // new: recorded as in progress, to be run
    in_progress,  // a repeat of a request still running: its answer will come
    answered,     // a repeat of an answered request: `answer` is the first answer
    busy,         // new, but kMaxInProgress requests run: refused, not recorded (not run)
    conflicting,  // names a known request but asks something else: refused, the first untouched
  };
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
  Admission admit(const SampleIdentity& request, Fingerprint content, Clock::time_point now = Clock::now()) {
    std::lock_guard lock(mutex_);
    forget_old(now);
    if (auto it = entries_.find(request); it != entries_.end()) {
      if (it->second.content != content) return {Seen::conflicting, std::nullopt};
      if (!it->second.answer) return {Seen::in_progress, std::nullopt};
      return {Seen::answered, it->second.answer};
    }
    if (in_progress_ >= kMaxInProgress) return {Seen::busy, std::nullopt};
    entries_.emplace(request, Entry{content, std::nullopt});
    ++in_progress_;
    return {Seen::first, std::nullopt};
  }

  // Keeps the first answer (a handler answering twice is harmless: the repeat gets the first).
  // From now on the request counts as answered and is kept for kKeep.
  void answered(const SampleIdentity& request, const Reply& reply, Clock::time_point now = Clock::now()) {
    std::lock_guard lock(mutex_);
    auto it = entries_.find(request);
    if (it == entries_.end() || it->second.answer) return;
    it->second.answer = reply;
    --in_progress_;
    answered_.emplace_back(now, request);
    forget_old(now);
  }

  std::size_t size() const {
    std::lock_guard lock(mutex_);
    return entries_.size();
  }
  std::size_t in_progress() const {
    std::lock_guard lock(mutex_);
    return in_progress_;
  }

 private:
  struct Entry {
    Fingerprint content;
    std::optional<Reply> answer;  // nullopt: in progress
  };

  // Only answered requests are forgotten; those in progress stay until they are answered.
  void forget_old(Clock::time_point now) {
    while (!answered_.empty() && (answered_.size() > kCapacity || now - answered_.front().first > kKeep)) {
      entries_.erase(answered_.front().second);
      answered_.pop_front();
    }
  }

  mutable std::mutex mutex_;
  std::map<SampleIdentity, Entry> entries_;
  std::deque<std::pair<Clock::time_point, SampleIdentity>> answered_;  // in the order answered
  std::size_t in_progress_ = 0;
};

}  // namespace lb::ddsl
