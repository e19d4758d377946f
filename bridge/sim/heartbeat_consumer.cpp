#include "sim/heartbeat_consumer.hpp"

#include <spdlog/spdlog.h>

#include <stdexcept>

#include "canopen/cob_id.hpp"
#include "canopen/sdo_abort.hpp"
#include "sim/little_endian.hpp"

namespace lb::sim {

namespace {
// 1016h sub n: the node-ID in bits 16..23, the consumer time (ms) in bits 0..15.
std::uint8_t node_of(std::uint32_t entry) { return static_cast<std::uint8_t>((entry >> 16) & 0xFF); }
std::chrono::milliseconds time_of(std::uint32_t entry) { return std::chrono::milliseconds(entry & 0xFFFF); }
}  // namespace

HeartbeatConsumer::HeartbeatConsumer(canopen::BusLoop& loop, canopen::ObjectDictionary& od,
                                     std::function<void()> on_event, std::function<void()> on_recovered)
    : loop_(loop), on_event_(std::move(on_event)), on_recovered_(std::move(on_recovered)) {
  timer_ = loop_.create_timer([this] { expired(); });
  using canopen::DataType;
  using canopen::ObjectAccess;
  if (!od.add(0x1016, 0, DataType::unsigned8, ObjectAccess::ro, {1}) ||
      !od.add(0x1016, 1, DataType::unsigned32, ObjectAccess::rw)) {
    throw std::logic_error("1016h could not be added");
  }
  (void)od.set_on_read(0x1016, 1, [this] {
    canopen::ObjectDictionary::Bytes b(4);
    for (std::size_t i = 0; i < b.size(); ++i) b[i] = static_cast<std::uint8_t>(entry_ >> (8 * i));
    return b;
  });
  (void)od.set_on_write(0x1016, 1, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    const auto entry = static_cast<std::uint32_t>(little_endian(v));
    const auto node = node_of(entry);
    if (node >= listening_.size()) return canopen::sdo_abort::value_range_exceeded;
    entry_ = entry;
    active_ = false;
    in_event_ = false;
    loop_.disarm_timer(timer_);
    if (node != 0 && !listening_[node]) {
      listening_[node] = true;
      loop_.on_frame(canopen::cob::heartbeat_base + node, [this](const can::CanFrame& f) { heartbeat(f); });
    }
    return std::nullopt;
  });
}

void HeartbeatConsumer::reset() {
  entry_ = 0;
  active_ = false;
  in_event_ = false;
  loop_.disarm_timer(timer_);
}

void HeartbeatConsumer::heartbeat(const can::CanFrame& frame) {
  if (entry_ == 0 || time_of(entry_).count() == 0 || frame.id != canopen::cob::heartbeat_base + node_of(entry_) ||
      frame.len != 1) {
    return;
  }
  active_ = true;
  loop_.arm_timer(timer_, time_of(entry_));
  if (in_event_) {
    in_event_ = false;
    on_recovered_();
  }
}

void HeartbeatConsumer::expired() {
  if (!active_ || in_event_) return;
  in_event_ = true;
  spdlog::warn("sim: the heartbeat of node {} consumed (1016h) missing for {} ms: heartbeat event", node_of(entry_),
               time_of(entry_).count());
  on_event_();
}

}  // namespace lb::sim
