#include "canopen/pdo_transmitter.hpp"

#include <algorithm>

namespace lb::canopen {

PdoTransmitter::PdoTransmitter(BusLoop& loop, Settings settings, Pack pack, Gate may_send, Sent sent)
    : loop_(loop), settings_(settings), pack_(std::move(pack)), may_send_(std::move(may_send)), sent_(std::move(sent)) {
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
    if (++sync_count_ >= type) {
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
  have_last_ = false;
  loop_.disarm_timer(inhibit_timer_);
  loop_.disarm_timer(event_timer_);
}

bool PdoTransmitter::data_changed() {
  can::CanFrame f;
  pack_(f);
  return !have_last_ || f.len != last_.len || !std::equal(f.data.begin(), f.data.begin() + f.len, last_.data.begin());
}

void PdoTransmitter::send_when_inhibit_allows() {
  const auto now = std::chrono::steady_clock::now();
  const auto earliest = last_sent_ + settings_.inhibit;
  if (settings_.inhibit.count() > 0 && have_last_ && now < earliest) {
    pending_ = true;
    loop_.arm_timer(inhibit_timer_, earliest - now);
    return;
  }
  send();
}

void PdoTransmitter::send() {
  pending_ = false;
  if (!may_send_()) return;
  can::CanFrame f;
  f.id = settings_.can_id;
  f.extended = settings_.extended;
  pack_(f);
  if (!loop_.send(f)) return;  // counted by the bus; the next trigger tries again
  last_ = f;
  have_last_ = true;
  last_sent_ = std::chrono::steady_clock::now();
  if (settings_.transmission_type >= 254 && settings_.event_timer.count() > 0) {
    loop_.arm_timer(event_timer_, settings_.event_timer);
  }
  if (sent_) sent_();
}

}  // namespace lb::canopen
