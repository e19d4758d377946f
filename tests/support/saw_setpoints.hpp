#pragma once
// A saw's set values as an application writes them (rt/<line>/<saw>/setpoint) and the bridge's
// answer to each (setpoint_result): the exchange every saw line test drives, on a virtual bus or on
// vcan. The answers are kept by a Collector, so a test can also wait on them itself.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <thread>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/sawPubSubTypes.h"
#include "support/collector.hpp"

namespace lb::test {

class SawSetpoints {
 public:
  using Result = linebridge_msgs::msg::SetpointResult;

  // The participant must outlive this object's use.
  lb::Result<void> open(lb::ddsl::Participant& dds, const std::string& line, const std::string& device) {
    dds_ = &dds;
    results_topic_ = lb::ddsl::topic_name(line, device, "setpoint_result");
    if (auto r = results_.subscribe(dds, results_topic_, lb::ddsl::QosKind::reply); !r) return r;
    auto w = dds.writer<linebridge_msgs::msg::SawSetpointPubSubType>(lb::ddsl::topic_name(line, device, "setpoint"),
                                                                     lb::ddsl::QosKind::command);
    if (!w) return w.error();
    writer_ = *w;
    return {};
  }

  // True once the bridge reads the set values and its answers reach this test, within the timeout.
  bool wait_matched(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (!matched()) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return true;
  }
  bool matched() const { return writer_.matched() > 0 && dds_->matched_writers(results_topic_) > 0; }

  // Writes one set value (program on or off, sync speed, product length, smooth-pipe count mode)
  // with the next request id; false when the writer refused it.
  bool write(std::uint64_t request_id, bool on, double percent, double length_m) {
    linebridge_msgs::msg::SawSetpoint sp;
    sp.request_id(request_id);
    sp.saw_program_on(on);
    sp.sync_speed_percent(percent);
    sp.product_length_m(length_m);
    sp.count_mode(linebridge_msgs::msg::SMOOTH_PIPE);
    return writer_.write(sp);
  }
  std::optional<Result> answer(std::uint64_t request_id, std::chrono::milliseconds timeout) {
    std::optional<Result> out;
    results_.wait(timeout, [&](const std::vector<Result>& all) {
      for (const auto& r : all) {
        if (r.request_id() == request_id) return out = r, true;
      }
      return false;
    });
    return out;
  }
  // write() and answer() with the next request id: the answer, or nothing within the timeout.
  std::optional<Result> send(bool on, double percent, double length_m, std::chrono::milliseconds timeout) {
    const auto id = ++request_id_;
    if (!write(id, on, percent, length_m)) return std::nullopt;
    return answer(id, timeout);
  }
  std::uint64_t last_request_id() const { return request_id_; }

  lb::ddsl::Writer<linebridge_msgs::msg::SawSetpointPubSubType>& writer() { return writer_; }
  Collector<linebridge_msgs::msg::SetpointResultPubSubType>& results() { return results_; }

 private:
  lb::ddsl::Participant* dds_ = nullptr;
  std::string results_topic_;
  lb::ddsl::Writer<linebridge_msgs::msg::SawSetpointPubSubType> writer_;
  Collector<linebridge_msgs::msg::SetpointResultPubSubType> results_;
  std::uint64_t request_id_ = 100;
};

}  // namespace lb::test
