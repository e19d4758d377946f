#include "canopen/active_master_watch.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <ctime>

#include "can/detail.hpp"

namespace lb::canopen {

ActiveMasterWatch::ActiveMasterWatch(BusLoop& loop, std::uint8_t master_node_id,
                                     std::chrono::milliseconds takeover_after,
                                     std::function<void(const Takeover&)> on_takeover)
    : loop_(loop),
      master_node_id_(master_node_id),
      takeover_after_(takeover_after),
      on_takeover_(std::move(on_takeover)) {
  timer_ = loop_.create_timer([this] { judge(); });
  registered_[master_node_id_] = true;
  loop_.on_frame(cob::heartbeat_base + master_node_id_, [this](const can::CanFrame& f) { heartbeat(f); });
  loop_.on_frame(cob::sync, [this](const can::CanFrame& f) {
    if (!active()) last_sync_ns_ = f.timestamp_ns;
  });
  loop_.on_frame(cob::nmt, [this](const can::CanFrame& f) {
    if (active() || f.len != 2) return;
    const auto node = f.data[1];
    if (node >= commands_.size()) return;
    if (node == 0) {
      commands_.fill(f.data[0]);
    } else {
      commands_[node] = f.data[0];
    }
  });
}

void ActiveMasterWatch::stand_by(std::uint8_t master_node_id) {
  if (active() || master_node_id == 0 || master_node_id >= registered_.size()) return;
  if (master_node_id != master_node_id_) last_heartbeat_ns_ = 0;  // another master's silence begins now
  master_node_id_ = master_node_id;
  if (!registered_[master_node_id]) {
    registered_[master_node_id] = true;
    loop_.on_frame(cob::heartbeat_base + master_node_id, [this](const can::CanFrame& f) { heartbeat(f); });
  }
  watching_ = true;
  started_ns_ = can::detail::realtime_ns();
  loop_.arm_timer(timer_, takeover_after_);
}

void ActiveMasterWatch::claim() {
  if (active()) return;
  loop_.disarm_timer(timer_);
  take_over(can::detail::realtime_ns());
}

std::optional<NmtCommand> ActiveMasterWatch::last_command(std::uint8_t node_id) const {
  if (node_id == 0 || node_id >= commands_.size() || commands_[node_id] == 0) return std::nullopt;
  return static_cast<NmtCommand>(commands_[node_id]);
}

void ActiveMasterWatch::heartbeat(const can::CanFrame& frame) {
  if (active() || frame.len < 1 || frame.id != cob::heartbeat_base + master_node_id_) return;
  last_heartbeat_ns_ = std::max(last_heartbeat_ns_, frame.timestamp_ns);
  if (watching_) loop_.arm_timer(timer_, takeover_after_);
}

// The master is silent when no heartbeat of it is stamped within takeover_after of now. A timer
// that fired after the loop was held up (this process stopped, a slow handler) fires before the
// frames that came meanwhile are read: those are read first.
void ActiveMasterWatch::judge() {
  if (active() || !watching_) return;
  if (loop_.input_pending()) return loop_.arm_timer(timer_, std::chrono::milliseconds(1));
  const auto now = can::detail::realtime_ns();
  const auto since = last_heartbeat_ns_ != 0 ? last_heartbeat_ns_ : started_ns_;
  const auto wait = std::chrono::nanoseconds(takeover_after_) - std::chrono::nanoseconds(now - since);
  if (wait > std::chrono::nanoseconds(0)) return loop_.arm_timer(timer_, wait);
  take_over(now);
}

void ActiveMasterWatch::take_over(std::int64_t now) {
  takeover_ = Takeover{last_heartbeat_ns_ != 0, master_node_id_, last_heartbeat_ns_, last_sync_ns_, now};
  const auto& t = *takeover_;
  if (t.master_heard && watching_) {
    spdlog::warn("{}: the master's heartbeat (node {}) silent for {} ms: taking the bus over", loop_.bus().uri(),
                 master_node_id_, (now - last_heartbeat_ns_) / 1'000'000);
  } else if (watching_) {
    spdlog::warn("{}: the active master (node {}) never sent a heartbeat within {} ms: mastering the bus",
                 loop_.bus().uri(), master_node_id_, takeover_after_.count());
  }
  on_takeover_(t);
}

std::string ActiveMasterWatch::describe() const {
  if (!takeover_) return {};
  const auto& t = *takeover_;
  const auto utc = fmt::format("{:%Y-%m-%d %H:%M:%S} UTC",
                               fmt::gmtime(static_cast<std::time_t>(t.at_ns / 1'000'000'000)));
  if (!t.master_heard) return "mastered from its start at " + utc + " (no master heard)";
  std::string gap = "first SYNC not sent yet";
  if (first_sync_ns_ != 0 && t.last_sync_ns != 0) {
    gap = fmt::format("SYNC gap {:.1f} ms (the master's last SYNC to this bridge's first)",
                      static_cast<double>(first_sync_ns_ - t.last_sync_ns) / 1e6);
  } else if (first_sync_ns_ != 0) {
    gap = "no SYNC of the master's was seen";
  }
  return fmt::format("took the bus over at {} from the master (node {}), its heartbeat silent for {} ms; {}", utc,
                     master_node_id_, (t.at_ns - t.last_heartbeat_ns) / 1'000'000, gap);
}

}  // namespace lb::canopen
