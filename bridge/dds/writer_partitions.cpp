#include "dds/writer_partitions.hpp"

#include <algorithm>

namespace lb::ddsl {

using eprosima::fastrtps::rtps::WriterDiscoveryInfo;

void WriterPartitions::on_publisher_discovery(eprosima::fastdds::dds::DomainParticipant*, WriterDiscoveryInfo&& info) {
  const Guid guid = info.info.guid();
  std::vector<std::string> now = info.info.m_qos.m_partition.getNames();
  std::lock_guard lock(mutex_);
  switch (info.status) {
    case WriterDiscoveryInfo::DISCOVERED_WRITER:
      if (now.empty()) {
        partitions_.erase(guid);  // the default partition: no device partition to remember
      } else {
        partitions_[guid] = std::move(now);
      }
      break;
    case WriterDiscoveryInfo::CHANGED_QOS_WRITER:
      if (auto it = partitions_.find(guid); it != partitions_.end()) {
        std::erase_if(it->second,
                      [&](const std::string& p) { return std::find(now.begin(), now.end(), p) == now.end(); });
      }
      break;
    case WriterDiscoveryInfo::REMOVED_WRITER: partitions_.erase(guid); break;
  }
}

std::vector<std::string> WriterPartitions::of(const Guid& writer) const {
  std::lock_guard lock(mutex_);
  const auto it = partitions_.find(writer);
  return it == partitions_.end() ? std::vector<std::string>{} : it->second;
}

bool WriterPartitions::contains(const Guid& writer, std::string_view partition) const {
  std::lock_guard lock(mutex_);
  const auto it = partitions_.find(writer);
  return it != partitions_.end() && std::find(it->second.begin(), it->second.end(), partition) != it->second.end();
}

}  // namespace lb::ddsl
