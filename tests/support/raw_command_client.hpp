#pragma once
// The line-wide command service at the wire: its request writer and a reader of every reply by the
// request it answers. For tests that write requests and repeats by hand (what ServiceClient does
// for the CLI), e.g. a repeat timed against a bridge restart.

#include <chrono>
#include <condition_variable>
#include <map>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::test {

class RawCommandClient {
 public:
  using Request = linebridge_msgs::srv::Command_Request;
  using Reply = linebridge_msgs::srv::Command_Response;
  using SampleIdentity = eprosima::fastrtps::rtps::SampleIdentity;
  using WriteParams = eprosima::fastrtps::rtps::WriteParams;

  // Throws when the endpoints cannot be created. Lives no longer than `dds`.
  RawCommandClient(ddsl::Participant& dds, const std::string& path) : dds_(dds), path_(path) {
    auto sub = dds.subscribe_scoped<linebridge_msgs::srv::Command_ResponsePubSubType>(
        ddsl::reply_topic(path), ddsl::QosKind::reply, [this](const Reply& r, const ddsl::fdds::SampleInfo& info) {
          {
            std::lock_guard lock(m_);
            by_request_[info.related_sample_identity].push_back(r);
          }
          cv_.notify_all();
        });
    if (!sub) throw std::runtime_error(sub.error().message);
    replies_ = std::move(*sub);
    auto w = dds.writer<linebridge_msgs::srv::Command_RequestPubSubType>(ddsl::request_topic(path),
                                                                         ddsl::QosKind::command);
    if (!w) throw std::runtime_error(w.error().message);
    requests_ = *w;
  }

  // Waits until a server's request reader and reply writer are both matched.
  bool matched(std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (requests_.matched() == 0 || dds_.matched_writers(ddsl::reply_topic(path_)) == 0) {
      if (std::chrono::steady_clock::now() > end) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return true;
  }
  // A request (params: out, its sample identity), or a repeat (params: in, the first request's).
  bool write(const Request& request, WriteParams& params) { return requests_.write(request, params); }
  bool wait_for(const SampleIdentity& request, std::size_t count, std::chrono::milliseconds timeout) {
    std::unique_lock lock(m_);
    return cv_.wait_for(lock, timeout, [&] { return by_request_[request].size() >= count; });
  }
  std::vector<Reply> of(const SampleIdentity& request) {
    std::lock_guard lock(m_);
    return by_request_[request];
  }

 private:
  ddsl::Participant& dds_;
  std::string path_;
  ddsl::Writer<linebridge_msgs::srv::Command_RequestPubSubType> requests_;
  std::mutex m_;
  std::condition_variable cv_;
  std::map<SampleIdentity, std::vector<Reply>> by_request_;
  std::unique_ptr<ddsl::Participant::Subscription> replies_;  // last: no callback once the rest is gone
};

}  // namespace lb::test
