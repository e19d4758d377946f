#pragma once
// Fast DDS's sample identity as the channel carries it (link::Identity), and back.

#include <fastdds/rtps/common/SampleIdentity.h>

#include <algorithm>

#include "link/channel_message.hpp"

namespace lb::ddsl {

inline link::Identity to_link(const eprosima::fastrtps::rtps::SampleIdentity& id) {
  link::Identity out;
  const auto& g = id.writer_guid();
  std::copy(std::begin(g.guidPrefix.value), std::end(g.guidPrefix.value), out.guid.begin());
  std::copy(std::begin(g.entityId.value), std::end(g.entityId.value), out.guid.begin() + 12);
  out.seq_high = id.sequence_number().high;
  out.seq_low = id.sequence_number().low;
  return out;
}

inline eprosima::fastrtps::rtps::SampleIdentity from_link(const link::Identity& id) {
  eprosima::fastrtps::rtps::SampleIdentity out;
  std::copy(id.guid.begin(), id.guid.begin() + 12, std::begin(out.writer_guid().guidPrefix.value));
  std::copy(id.guid.begin() + 12, id.guid.end(), std::begin(out.writer_guid().entityId.value));
  out.sequence_number().high = id.seq_high;
  out.sequence_number().low = id.seq_low;
  return out;
}

}  // namespace lb::ddsl
