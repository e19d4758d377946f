#include "dds/lost_samples.hpp"

#include <spdlog/spdlog.h>

namespace lb::ddsl {

void LostSamples::seen(const eprosima::fastrtps::rtps::SampleIdentity& id, const std::string& topic) {
  const std::uint64_t sn = id.sequence_number().to64long();
  std::uint64_t gap = 0;
  std::unique_lock lock(mutex_);
  if (last_.size() >= kMaxWriters && last_.find(id.writer_guid()) == last_.end()) last_.clear();
  auto [it, first] = last_.try_emplace(id.writer_guid(), sn);
  if (!first) {
    if (sn > it->second + 1) gap = sn - it->second - 1;
    if (sn > it->second) it->second = sn;
  }
  if (gap == 0) return;
  lost_.fetch_add(gap, std::memory_order_relaxed);
  if (!log_.allow()) return;
  const auto held_back = log_.held_back();
  lock.unlock();
  spdlog::warn("{}: {} sample(s) of one writer lost before the bridge read them (written faster than read; "
               "{} lost in all){}",
               topic, gap, lost(),
               held_back == 0 ? std::string() : " (" + std::to_string(held_back) + " more reports not logged)");
}

}  // namespace lb::ddsl
