#include "canopen/other_master.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "canopen/cob_id.hpp"

namespace lb::canopen {

OtherMasterWatch::OtherMasterWatch(BusLoop& loop, Policy policy, std::uint8_t own_node_id) : loop_(loop), policy_(policy) {
  quiet_timer_ = loop_.create_timer([this] { quiet(); });
  loop_.on_frame(cob::sync, [this](const can::CanFrame& f) { seen(f, "a SYNC from another producer"); });
  loop_.on_frame(cob::nmt, [this](const can::CanFrame& f) { seen(f, "an NMT command from another master"); });
  if (own_node_id != 0) {
    loop_.on_frame(cob::heartbeat_base + own_node_id,
                   [this](const can::CanFrame& f) { seen(f, "a heartbeat on the bridge's own node-ID"); });
  }
}

void OtherMasterWatch::watch_rpdo(std::uint32_t can_id, bool extended) {
  const auto handler = [this](const can::CanFrame& f) { seen(f, "an RPDO the bridge sends, from someone else"); };
  if (extended) loop_.on_extended_frame(can_id, handler);
  else loop_.on_frame(can_id, handler);
}

void OtherMasterWatch::seen(const can::CanFrame& frame, const char* what) {
  ++frames_;
  last_ = fmt::format("{} ({:03X}h)", what, frame.id);
  const auto now = std::chrono::steady_clock::now();
  recent_.push_back(now);
  while (!recent_.empty() && now - recent_.front() > std::chrono::seconds(1)) recent_.pop_front();
  const bool heard = recent_.size() >= kTrigger;
  if (log_.allow()) {
    spdlog::error("{}: {}: another master is on this bus ({} such frames so far){}{}", loop_.bus().uri(), last_, frames_,
                  heard && policy_ == Policy::yield ? "; the bridge transmits nothing here until it is silent for 5 s"
                                                    : "",
                  held_back_note(log_));
  }
  if (!heard || policy_ != Policy::yield) return;
  loop_.arm_timer(quiet_timer_, kQuiet);
  if (yielding_) return;
  yielding_ = true;
  loop_.hold_transmission(true);
}

void OtherMasterWatch::quiet() {
  if (!yielding_) return;
  yielding_ = false;
  recent_.clear();
  loop_.hold_transmission(false);
  spdlog::warn("{}: the other master has been silent for {} s: the bridge transmits again", loop_.bus().uri(), kQuiet.count());
}

}  // namespace lb::canopen
