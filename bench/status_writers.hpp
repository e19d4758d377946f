#pragma once
// The saws' status writers of bus 0 as the bridge makes them (its type, topic and QoS), for the
// programs that stand in for the bridge's DDS side. Each gets its first sample at once, as from the
// bridge: the device exists before its data.

#include <cstddef>
#include <vector>

#include "base/result.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/sawPubSubTypes.h"
#include "names.hpp"

namespace lb::bench {

struct StatusWriters {
  std::vector<lb::ddsl::Writer<linebridge_msgs::msg::SawStatusPubSubType>> writers;
  std::vector<linebridge_msgs::msg::SawStatus> samples;  // the last sample of each, to update and write
};

inline lb::Result<StatusWriters> status_writers(lb::ddsl::Participant& dds, int devices) {
  StatusWriters out;
  out.samples.resize(static_cast<std::size_t>(devices));
  for (int d = 0; d < devices; ++d) {
    auto w = dds.writer<linebridge_msgs::msg::SawStatusPubSubType>(lb::ddsl::topic_name(kLine, device_name(0, d),
                                                                                        "status"),
                                                                   lb::ddsl::QosKind::state);
    if (!w) return w.error();
    out.writers.push_back(*w);
    out.writers.back().write(out.samples[static_cast<std::size_t>(d)]);
  }
  return out;
}

}  // namespace lb::bench
