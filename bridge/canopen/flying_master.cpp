#include "canopen/flying_master.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "can/detail.hpp"
#include "canopen/cob_id.hpp"
#include "canopen/other_master.hpp"

namespace lb::canopen {

namespace {

can::CanFrame service(std::uint32_t id) {
  can::CanFrame f;
  f.id = id;
  return f;
}

}  // namespace

std::string_view to_string(FlyingMaster::State state) {
  switch (state) {
    case FlyingMaster::State::detecting: return "detecting";
    case FlyingMaster::State::standing_by: return "standing by";
    case FlyingMaster::State::negotiating: return "negotiating";
    case FlyingMaster::State::active: return "active";
    case FlyingMaster::State::stepped_back: return "stepped back";
  }
  return "?";
}

FlyingMaster::FlyingMaster(BusLoop& loop, Settings settings, OtherMasterWatch* other, Callbacks callbacks)
    : loop_(loop), settings_(settings), other_(other), callbacks_(std::move(callbacks)) {
  wait_timer_ = loop_.create_timer([this] { state_ == State::detecting ? detection_step() : waited(); });
  cycle_timer_ = loop_.create_timer([this] {
    if (state_ == State::active) (void)loop_.send_negotiation(service(cob::force_negotiation));
  });
  tick_timer_ = loop_.create_timer([this] { tick(); });
  loop_.on_frame(cob::active_master_answer, [this](const can::CanFrame& f) { answer_seen(f); });
  loop_.on_frame(cob::negotiation_request, [this](const can::CanFrame&) { request_seen(); });
  loop_.on_frame(cob::active_master_request, [this](const can::CanFrame&) { active_request_seen(); });
  loop_.on_frame(cob::force_negotiation, [this](const can::CanFrame&) { force_seen(); });
  // 74h/75h (detect-master request and answer) concern self-starting slaves (1F91h): not this bridge's.
  loop_.on_frame(0x074, [](const can::CanFrame&) {});
  loop_.on_frame(0x075, [](const can::CanFrame&) {});
  loop_.on_frame(cob::heartbeat_base + settings_.node_id, [this](const can::CanFrame& f) { master_heartbeat_seen(f); });
}

void FlyingMaster::start() {
  state_ = State::detecting;
  asked_ = false;
  last_tick_ns_ = can::detail::realtime_ns();
  loop_.arm_timer(tick_timer_, settings_.stall / 4, settings_.stall / 4);
  event(
      fmt::format("power-up: listening {} ms before asking for an active master", settings_.negotiation_delay.count()));
  loop_.arm_timer(wait_timer_, settings_.negotiation_delay);
}

// The delay over: is there an active master? Then the detection timeout over: none answered.
void FlyingMaster::detection_step() {
  if (!asked_) {
    asked_ = true;
    (void)loop_.send_negotiation(service(cob::active_master_request));
    loop_.arm_timer(wait_timer_, settings_.detect_timeout);
    return;
  }
  event("no active master answered (73h): negotiating");
  negotiate(true);
}

void FlyingMaster::negotiate(bool request) {
  if (state_ == State::negotiating || state_ == State::stepped_back) return;
  was_active_ = state_ == State::active;
  state_ = State::negotiating;
  if (other_ != nullptr) other_->stand_by(true);
  if (request) (void)loop_.send_negotiation(service(cob::negotiation_request));
  const auto wait = settings_.priority * settings_.priority_slot + settings_.node_id * settings_.device_slot;
  loop_.arm_timer(wait_timer_, wait);
}

void FlyingMaster::waited() {
  if (state_ != State::negotiating) return;
  if (other_ != nullptr) other_->stand_by(false);
  if (was_active_) {
    state_ = State::active;
    announce();
    event("negotiation won: mastering on");
    return;
  }
  event("negotiation won: mastering the bus");
  callbacks_.win();  // the bridge masters the bus and calls mastering()
}

void FlyingMaster::mastering() {
  if (state_ == State::stepped_back) return;
  loop_.disarm_timer(wait_timer_);
  if (other_ != nullptr) other_->stand_by(false);
  state_ = State::active;
  announce();
  loop_.arm_timer(cycle_timer_, settings_.detect_cycle, settings_.detect_cycle);
  event(fmt::format("mastering the bus: announced (71h), a force negotiation (76h) every {} ms",
                    settings_.detect_cycle.count()));
}

void FlyingMaster::announce() {
  auto f = service(cob::active_master_answer);
  f.len = 2;
  f.data[0] = settings_.priority;
  f.data[1] = settings_.node_id;
  (void)loop_.send_negotiation(f);
}

void FlyingMaster::stand_by(std::uint8_t node) {
  loop_.disarm_timer(wait_timer_);
  if (other_ != nullptr) other_->stand_by(true);
  state_ = State::standing_by;
  active_node_ = node;
  event(fmt::format("standing by the active master (node {})", node));
  callbacks_.stand_by(node);
}

void FlyingMaster::step_back(const std::string& why) {
  if (state_ == State::stepped_back) return;
  state_ = State::stepped_back;
  loop_.disarm_timer(wait_timer_);
  loop_.disarm_timer(cycle_timer_);
  event("stepped back: " + why);
  spdlog::warn("{}: stepping back to standby: {}", loop_.bus().uri(), why);
  callbacks_.step_back(why);
}

bool FlyingMaster::better(std::uint8_t priority, std::uint8_t node) const {
  return priority < settings_.priority || (priority == settings_.priority && node <= settings_.node_id);
}

void FlyingMaster::answer_seen(const can::CanFrame& frame) {
  if (frame.len != 2) {
    if (log_.allow()) {
      spdlog::warn("{}: a 71h (active master answer) with {} data bytes instead of 2 (priority, node-ID): ignored{}",
                   loop_.bus().uri(), frame.len, held_back_note(log_));
    }
    return;
  }
  const std::uint8_t priority = frame.data[0];
  const std::uint8_t node = frame.data[1];
  if (priority == settings_.priority && node == settings_.node_id && log_.allow()) {
    spdlog::error("{}: another master answers with this bridge's own priority {} and node-ID {}: give each bridge of "
                  "the pair its own flying_master priority{}",
                  loop_.bus().uri(), priority, node, held_back_note(log_));
  }
  switch (state_) {
    case State::detecting: return stand_by(node);
    case State::standing_by:
      if (node != active_node_) stand_by(node);
      return;
    case State::negotiating:
      if (!better(priority, node)) return;  // this bridge's own answer at the end of its wait decides
      if (was_active_)
        return step_back(fmt::format("master node {} (priority {}) won the negotiation", node, priority));
      return stand_by(node);
    case State::active:
      if (stalled_at(frame.timestamp_ns))
        return step_back(fmt::format("master node {} took the bus over while this bridge's loop was stalled", node));
      event(fmt::format("another active master (node {}, priority {}): negotiating", node, priority));
      return negotiate(true);
    case State::stepped_back: return;
  }
}

void FlyingMaster::request_seen() {
  if (state_ == State::detecting || state_ == State::active) {
    event("a negotiation was requested (72h)");
    negotiate(false);
  }
}

void FlyingMaster::active_request_seen() {
  if (state_ == State::active || (state_ == State::negotiating && was_active_)) announce();
}

void FlyingMaster::force_seen() {
  if (state_ != State::active) return;
  event("another master forces a negotiation (76h)");
  negotiate(true);
}

// The line's master heartbeat, which this bridge produces when it masters the bus (it never receives
// its own frames): another master is active.
void FlyingMaster::master_heartbeat_seen(const can::CanFrame& frame) {
  switch (state_) {
    case State::detecting: return stand_by(settings_.node_id);
    case State::negotiating:
      if (!was_active_) stand_by(settings_.node_id);
      return;
    case State::active:
      if (stalled_at(frame.timestamp_ns))
        return step_back("another master's heartbeat came while this bridge's loop was stalled");
      event("another master's heartbeat on this bridge's node-ID: negotiating");
      return negotiate(true);
    case State::standing_by:
    case State::stepped_back: return;
  }
}

void FlyingMaster::tick() {
  const auto now = can::detail::realtime_ns();
  if (now - last_tick_ns_ > std::chrono::nanoseconds(settings_.stall).count()) {
    stall_from_ns_ = last_tick_ns_;
    stall_to_ns_ = now;
  }
  last_tick_ns_ = now;
}

// Stamped while this loop did not run: during the last stall the tick saw, or after the last tick
// by more than a stall (the frame is dispatched before the tick that would see the stall). Or just
// after that stall, by less than a stall: the standby judged this master silent during it, and its
// 71h went out a timer's latency later.
bool FlyingMaster::stalled_at(std::int64_t stamp_ns) const {
  const auto stall = std::chrono::nanoseconds(settings_.stall).count();
  return stamp_ns > last_tick_ns_ + stall || (stall_from_ns_ < stamp_ns && stamp_ns < stall_to_ns_ + stall);
}

void FlyingMaster::event(std::string text) {
  spdlog::info("{}: flying master: {}", loop_.bus().uri(), text);
  last_event_ = std::move(text);
}

std::string FlyingMaster::describe() const {
  return fmt::format("{} (priority {}, node {}): {}", to_string(state_), settings_.priority, settings_.node_id,
                     last_event_);
}

}  // namespace lb::canopen
