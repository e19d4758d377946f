#include "gateways/node/momentary_commands.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace lb::gateways {

namespace {

double ms(std::chrono::nanoseconds d) { return std::chrono::duration<double, std::milli>(d).count(); }

// How a pulse ended, before the per-press frames and duration are filled in.
MomentaryCommands::Outcome ended(bool on_bus, std::string message = {}) {
  MomentaryCommands::Outcome o;
  o.on_bus = on_bus;
  o.message = std::move(message);
  return o;
}

}  // namespace

MomentaryCommands::MomentaryCommands(canopen::BusLoop& loop, std::function<void(unsigned, bool)> set_bit,
                                     std::function<void()> changed, std::chrono::milliseconds hold,
                                     std::chrono::milliseconds patience)
    : loop_(loop), set_bit_(std::move(set_bit)), changed_(std::move(changed)), hold_(hold), patience_(patience) {}

MomentaryCommands::Pulse& MomentaryCommands::pulse(unsigned bit) {
  auto it = pulses_.find(bit);
  if (it == pulses_.end()) {
    // One timer per bit, created on first use (on the loop thread, as BusLoop allows); a bit's
    // entry stays, since timers cannot be destroyed.
    Pulse p;
    p.timer = loop_.create_timer([this, bit] { on_timer(bit); });
    it = pulses_.emplace(bit, std::move(p)).first;
  }
  return it->second;
}

bool MomentaryCommands::held(unsigned bit) const {
  const auto it = pulses_.find(bit);
  return it != pulses_.end() && !it->second.presses.empty() && it->second.state != State::releasing;
}

std::optional<MomentaryCommands::Clock::time_point> MomentaryCommands::release_due(const Pulse& p) const {
  std::optional<Clock::time_point> due;
  for (const auto& press : p.presses) {
    if (!press.first) return std::nullopt;
    due = std::max(due.value_or(*press.first), *press.first);
  }
  if (due) *due += hold_;
  return due;
}

void MomentaryCommands::press(unsigned bit, Done done) {
  Pulse& p = pulse(bit);
  p.presses.push_back({std::move(done), std::nullopt, 0});
  if (p.state == State::releasing) p.state = State::on;  // pressed again before the release went out
  set_bit_(bit, true);
  // Until this press is in a frame, nothing is due but the patience.
  loop_.arm_timer(p.timer, patience_);
  changed_();
}

void MomentaryCommands::before_frame() {
  const auto now = Clock::now();
  for (auto& [bit, p] : pulses_) {
    if (p.state != State::on) continue;
    const auto due = release_due(p);
    if (due && now >= *due) release(bit, p);  // this very frame clears it
  }
}

void MomentaryCommands::frame_sent(Clock::time_point at) {
  for (auto& [bit, p] : pulses_) {
    if (p.presses.empty()) continue;
    if (p.state == State::releasing) {
      finish(bit, p, ended(true), at);
      continue;
    }
    for (auto& press : p.presses) {
      if (!press.first) press.first = at;
      ++press.frames;
    }
    p.state = State::on;
    p.last_frame = at;
    const auto due = release_due(p);
    loop_.arm_timer(p.timer, due ? std::max(*due - Clock::now(), Clock::duration::zero()) : Clock::duration(patience_));
  }
}

void MomentaryCommands::frame_not_sent(std::string_view why) {
  bool cleared = false;
  for (auto& [bit, p] : pulses_) {
    if (p.presses.empty()) continue;
    if (p.state == State::releasing) {
      // It was on the bus long enough; only its end is late.
      finish(bit, p,
             ended(true,
                   fmt::format("the frame that releases it was not sent ({}): the device gets it with the next RPDO "
                               "it may take",
                               why)),
             std::nullopt);
      continue;
    }
    set_bit_(bit, false);
    cleared = true;
    finish(bit, p, ended(false, std::string(why)), std::nullopt);
  }
  // The cleared bits reach the image's users after this frame's bookkeeping (not from inside it).
  if (cleared) loop_.post(changed_);
}

void MomentaryCommands::on_timer(unsigned bit) {
  Pulse& p = pulses_.at(bit);
  if (p.presses.empty()) return;
  const auto now = Clock::now();
  const auto patience = fmt::format("no RPDO carrying the control word went out within {} ms", patience_.count());
  switch (p.state) {
    case State::waiting:
    case State::on: {
      const auto due = release_due(p);
      if (!due) {  // a press still without a frame after the patience
        set_bit_(bit, false);
        finish(bit, p, ended(false, patience), std::nullopt);
        changed_();
        return;
      }
      if (now < *due) return loop_.arm_timer(p.timer, *due - now);
      // An event-driven RPDO sends the release at once; a synchronous one at its next SYNC.
      release(bit, p);
      changed_();
      return;
    }
    case State::releasing:
      finish(bit, p, ended(true, patience + " to release it: the device gets the release with the next RPDO"),
             std::nullopt);
      return;
  }
}

void MomentaryCommands::release(unsigned bit, Pulse& p) {
  set_bit_(bit, false);
  p.state = State::releasing;
  loop_.arm_timer(p.timer, patience_);  // the release must go out too
}

void MomentaryCommands::finish(unsigned bit, Pulse& p, Outcome base, std::optional<Clock::time_point> released_at) {
  (void)bit;
  std::vector<Press> presses = std::move(p.presses);
  const auto last_frame = p.last_frame;
  p = Pulse{State::waiting, {}, p.timer, std::nullopt};
  loop_.disarm_timer(p.timer);
  for (auto& press : presses) {
    Outcome o = base;
    o.frames = press.frames;
    const auto end = released_at ? released_at : last_frame;
    if (press.first && end) o.held = *end - *press.first;
    if (!o.on_bus) {
      o.message =
          press.frames == 0
              ? fmt::format("{}: the command never reached the bus", base.message)
              : fmt::format("interrupted after {} frame(s) over {:.1f} ms (less than the {} ms it must be held): {}",
                            press.frames, ms(o.held), hold_.count(), base.message);
    }
    if (press.done) press.done(o);
  }
}

}  // namespace lb::gateways
