#pragma once
// A device's set-value side as an application uses it: its status, the answers to its set values
// and a writer of them, ready once the device is operational and the writer and the answers are
// matched with the bridge both ways (a set value written then is read and answered).

#include <chrono>
#include <stdexcept>
#include <string>

#include "msgs/commonPubSubTypes.h"
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

}  // namespace lb::test
