#include "canopen/pdo_transmitter.hpp"

#include <algorithm>

namespace lb::canopen {

PdoTransmitter::PdoTransmitter(BusLoop& loop, Settings settings, Hooks hooks)
    : loop_(loop), settings_(settings), hooks_(std::move(hooks)) {
  inhibit_timer_ = loop_.create_timer([this] {
    if (pending_) send();
  });
  event_timer_ = loop_.create_timer([this] { send_when_inhibit_allows(); });
}

void PdoTransmitter::on_sync() {
  const auto type = settings_.transmission_type;
  if (type == 0) {
    if (data_changed()) send();
  } else if (type <= 240) {
    if (++sync_count_ >= type || owed_) {
      sync_count_ = 0;
      send();
    }
  }
}

void PdoTransmitter::on_data() {
  if (settings_.transmission_type >= 254 && data_changed()) send_when_inhibit_allows();
}

void PdoTransmitter::resend() {
  have_last_ = false;
  on_data();
}

void PdoTransmitter::reconfigure(Settings settings) {
  settings_ = settings;
  sync_count_ = 0;
  pending_ = false;
  owed_ = false;
  have_last_ = false;
  loop_.disarm_timer(inhibit_timer_);
  loop_.disarm_timer(event_timer_);
}

bool PdoTransmitter::data_changed() {
  can::CanFrame f;
  hooks_.pack(f);
  return !have_last_ || f.len != last_.len || !std::equal(f.data.begin(), f.data.begin() + f.len, last_.data.begin());
}

void PdoTransmitter::send_when_inhibit_allows() {
  // From the last frame really sent, whatever made this one due: a resend after an NMT or online
  // change is still a frame of this PDO on the bus, and the inhibit time protects the bus.
  if (settings_.inhibit.count() > 0 && last_sent_) {
    const auto now = std::chrono::steady_clock::now();
    const auto earliest = *last_sent_ + settings_.inhibit;
    if (now < earliest) {
      pending_ = true;
      loop_.arm_timer(inhibit_timer_, earliest - now);
      return;
    }
  }
  send();
}

bool PdoTransmitter::held_back_quiet() {
  if (quiet_over_) return false;  // no clock read per frame once the quiet time is over
  const auto now = std::chrono::steady_clock::now();
  if (now >= quiet_until_) {
    quiet_over_ = true;
    return false;
  }
  if (settings_.transmission_type >= 254) {
    pending_ = true;
    loop_.arm_timer(inhibit_timer_, quiet_until_ - now);
  } else {
    // Not sent between two SYNCs: a device may take a synchronous PDO only in its SYNC window.
    owed_ = true;
  }
  return true;
}

void PdoTransmitter::send() {
  pending_ = false;
  if (held_back_quiet()) return;
  owed_ = false;
  if (!hooks_.may_send()) return refused(Refusal::gate);
  if (hooks_.before_send) hooks_.before_send();
  can::CanFrame f;
  f.id = settings_.can_id;
  f.extended = settings_.extended;
  hooks_.pack(f);
  // Taken as the frame is handed to the bus (a recording stamps it at the same moment), not after
  // the send returns: what this frame starts or ends (a momentary command's hold, the inhibit
  // time) is measured from frame to frame on the bus.
  const auto at = std::chrono::steady_clock::now();
  const bool sent = (hooks_.stopping && hooks_.stopping() ? loop_.send_stop(f) : loop_.send(f)).has_value();
  if (!sent) return refused(Refusal::bus);  // counted by the bus
  last_ = f;
  have_last_ = true;
  last_sent_ = at;
  arm_event_timer();
  if (hooks_.sent) hooks_.sent(f, at);
}

Result<void> PdoTransmitter::send_now() {
  pending_ = false;
  owed_ = false;
  loop_.disarm_timer(inhibit_timer_);
  if (hooks_.before_send) hooks_.before_send();
  can::CanFrame f;
  f.id = settings_.can_id;
  f.extended = settings_.extended;
  hooks_.pack(f);
  const auto at = std::chrono::steady_clock::now();
  if (auto r = loop_.send_stop(f); !r) {
    refused(Refusal::bus);
    return r;
  }
  last_ = f;
  have_last_ = true;
  last_sent_ = at;
  arm_event_timer();
  if (hooks_.sent) hooks_.sent(f, at);
  return {};
}

void PdoTransmitter::refused(Refusal why) {
  // The next trigger tries again: unchanged data still counts as unsent (last_ is the last frame
  // sent), and an event-driven PDO's event timer keeps running, so a refused send does not
  // silence it until its data changes.
  arm_event_timer();
  if (hooks_.not_sent) hooks_.not_sent(why);
}

void PdoTransmitter::arm_event_timer() {
  if (settings_.transmission_type >= 254 && settings_.event_timer.count() > 0) {
    loop_.arm_timer(event_timer_, settings_.event_timer);
  }
}

}  // namespace lb::canopen
