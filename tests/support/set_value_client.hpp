#pragma once
// A device's set-value side as an application uses it: its status, the answers to its set values
// and a writer of them, ready once the device is operational and the writer and the answers are
// matched with the bridge both ways (a set value written then is read and answered).

#include <chrono>
#include <stdexcept>
#include <string>

#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/line_harness.hpp"

namespace lb::test {

template <class StatusPubSubType, class SetpointPubSubType>
struct SetValueClient {
  // Throws (with the line's logs) when the device never becomes operational or nothing matches.
  SetValueClient(LineHarness& line, const std::string& device, const std::string& setpoint_topic = "setpoint",
                 const std::string& result_topic = "setpoint_result")
      : status(line.operational_status<StatusPubSubType>(device)),
        results(
            line.collect<linebridge_msgs::msg::SetpointResultPubSubType>(device, result_topic, ddsl::QosKind::reply)),
        writer(writer_of(line, line.topic(device, setpoint_topic))) {
    if (!line.wait_matched(writer, line.topic(device, result_topic)))
      throw std::runtime_error(device + ": the set-value writer never matched the bridge\n" + line.logs());
  }

  // True once the answer to `request_id` says `accepted` (the first answer to it decides).
  bool answered(std::uint64_t request_id, bool accepted = true,
                std::chrono::milliseconds timeout = std::chrono::seconds(30)) {
    return results.wait(timeout, [&](const std::vector<linebridge_msgs::msg::SetpointResult>& v) {
      for (const auto& r : v) {
        if (r.request_id() == request_id) return r.accepted() == accepted;
      }
      return false;
    });
  }

  Collector<StatusPubSubType> status;
  Collector<linebridge_msgs::msg::SetpointResultPubSubType> results;
  ddsl::Writer<SetpointPubSubType> writer;

 private:
  static ddsl::Writer<SetpointPubSubType> writer_of(LineHarness& line, const std::string& topic) {
    auto w = line.dds().writer<SetpointPubSubType>(topic, ddsl::QosKind::command);
    if (!w) throw std::runtime_error(topic + ": " + w.error().message);
    return *w;
  }
};

// Saw 3.1 set values: program on (count mode smooth pipe), a sync speed and a product length.
inline linebridge_msgs::msg::SawSetpoint saw_set_value(std::uint64_t id, double speed_percent = 50,
                                                       double length_m = 1.2) {
  linebridge_msgs::msg::SawSetpoint sp;
  sp.request_id(id);
  sp.saw_program_on(true);
  sp.sync_speed_percent(speed_percent);
  sp.product_length_m(length_m);
  return sp;
}

}  // namespace lb::test
