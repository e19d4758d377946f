#pragma once
// The partitions each remote DataWriter was matched with, as discovery announced them, for the
// per-device check of line-wide requests in a secured line (security_policy.hpp).
//
// Fast DDS checks a remote writer's partitions against its permissions when it is discovered, but
// when the writer later changes its partitions (PartitionQosPolicy is mutable) the new ones fail
// the check without unmatching the writer (SecurityManager::discovered_writer only logs). So what
// counts is what was checked at discovery, narrowed by every later change: a partition a writer
// adds after matching is never trusted.

#include <fastdds/dds/domain/DomainParticipantListener.hpp>

#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace lb::ddsl {

class WriterPartitions : public eprosima::fastdds::dds::DomainParticipantListener {
 public:
  using Guid = eprosima::fastrtps::rtps::GUID_t;

  // Runs inside discovery, before the writer is matched with any local reader.
  void on_publisher_discovery(eprosima::fastdds::dds::DomainParticipant* participant,
                              eprosima::fastrtps::rtps::WriterDiscoveryInfo&& info) override;

  // True when the writer was discovered in this partition and has not left it since.
  bool contains(const Guid& writer, std::string_view partition) const;
  // Every partition the writer is trusted in (for the DDS process to hand on with its samples).
  std::vector<std::string> of(const Guid& writer) const;

 private:
  mutable std::mutex mutex_;
  std::map<Guid, std::vector<std::string>> partitions_;
};

}  // namespace lb::ddsl
