#include "canopen/other_master.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

#include "canopen/cob_id.hpp"

namespace lb::canopen {

OtherMasterWatch::OtherMasterWatch(BusLoop& loop, Policy policy, std::uint8_t own_node_id)
    : loop_(loop), policy_(policy) {
  quiet_timer_ = loop_.create_timer([this] { quiet(); });
  loop_.on_frame(cob::sync, [this](const can::CanFrame& f) { sync_seen(f); });
  loop_.on_frame(cob::nmt, [this](const can::CanFrame& f) { seen(f, "an NMT command from another master"); });
  if (own_node_id != 0) {
    loop_.on_frame(cob::heartbeat_base + own_node_id,
                   [this](const can::CanFrame& f) { seen(f, "a heartbeat on the bridge's own node-ID"); });
  }
}

void OtherMasterWatch::watch_rpdo(std::uint32_t can_id, bool extended) {
  const auto handler = [this](const can::CanFrame& f) { seen(f, "an RPDO the bridge sends, from someone else"); };
  if (extended)
    loop_.on_extended_frame(can_id, handler);
  else
    loop_.on_frame(can_id, handler);
}

void OtherMasterWatch::seen(const can::CanFrame& frame, const char* what) {
  if (standing_by_) return;
  ++frames_;
  last_ = fmt::format("{} ({:03X}h)", what, frame.id);
  if (log_.allow()) {
    spdlog::error("{}: {}: another master or a misconfigured device is on this bus ({} such frames so far){}{}",
                  loop_.bus().uri(), last_, frames_,
                  yielding_ ? "; the bridge transmits nothing here until the other SYNC producer is silent for 5 s"
                            : "",
                  held_back_note(log_));
  }
}

std::chrono::nanoseconds OtherMasterWatch::max_gap() const {
  return std::max<std::chrono::nanoseconds>(kEvidenceGap, 3 * own_period_);
}

void OtherMasterWatch::sync_seen(const can::CanFrame& frame) {
  if (standing_by_) return;
  const std::int64_t now = frame.timestamp_ns;
  const bool continues = run_syncs_ != 0 && now >= last_sync_ns_ && now - last_sync_ns_ <= max_gap().count();
  if (!continues) {  // a new run begins: whatever the last one gave is gone
    run_start_ns_ = now;
    run_syncs_ = 0;
  }
  last_sync_ns_ = now;
  ++run_syncs_;
  const auto span = std::chrono::nanoseconds(now - run_start_ns_);
  const bool evidence = run_syncs_ >= kEvidence && span >= kEvidenceSpan;
  if (policy_ == Policy::yield && evidence && !yielding_) {
    yielding_ = true;
    ++yields_;
    loop_.hold_transmission(true);
    spdlog::error("{}: another master's SYNC runs on this bus ({} SYNCs in {} ms, none more than {} ms apart): the "
                  "bridge transmits nothing here but stops, and refuses set values and commands, until it has been "
                  "silent for {} s",
                  loop_.bus().uri(), run_syncs_, std::chrono::duration_cast<std::chrono::milliseconds>(span).count(),
                  std::chrono::duration_cast<std::chrono::milliseconds>(max_gap()).count(), kQuiet.count());
  }
  // Only the producer that made the evidence keeps the yield: a stray SYNC later is no run.
  if (yielding_ && evidence) loop_.arm_timer(quiet_timer_, kQuiet);
  seen(frame, "a SYNC from another producer");
}

void OtherMasterWatch::quiet() {
  if (!yielding_) return;
  yielding_ = false;
  run_syncs_ = 0;
  loop_.hold_transmission(false);
  spdlog::warn("{}: the other master has been silent for {} s: the bridge transmits again", loop_.bus().uri(),
               kQuiet.count());
}

}  // namespace lb::canopen
