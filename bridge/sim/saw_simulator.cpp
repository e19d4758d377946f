#include "sim/saw_simulator.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>

#include "sim/device_dictionary.hpp"

namespace lb::sim {

using canopen::NmtState;
using profiles::PdoDirection;

namespace {
// A cut shows in the status word at least this long (CiA 420-1: request bits >= 100 ms).
constexpr auto kCuttingPulse = std::chrono::milliseconds(150);
constexpr double kMaxStep = 0.1;  // s: a stalled loop must not make the product jump
}  // namespace

SawSimulator::SawSimulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile)
    : loop_(loop),
      device_(device),
      profile_(profile),
      nmt_(loop, device.node_id, device.simulation.heartbeat_period, [this] { reset_application(); }),
      sdo_(loop, device.node_id, make_device_dictionary(device, profile)) {
  status_word_ = slot("status_word");
  control_word_ = slot("control_word");
  counter_value_ = slot("counter_value");
  saw_counter_ = slot("actual_saw_counter");
  product_speed_ = slot("product_speed");
  sync_speed_set_ = slot("saw_sync_speed_set_value");
  length_set_ = slot("product_length_set_value");
  speed_max_ = slot("saw_sync_speed_set_maximum");
  cw_program_on_ = bit("control_word", "saw_program_on");
  cw_change_of_length_ = bit("control_word", "change_of_length");
  sw_ready_ = bit("status_word", "saw_ready");
  sw_cutting_ = bit("status_word", "saw_cutting");
  sw_program_enabled_ = profile_.bitset("status_word")->bit("saw_program_enabled").value_or(sw_ready_);

  tpdo_bindings_.reserve(device_.pdos.size());  // the transmitters keep pointers into it
  for (const auto& pdo : device_.pdos) {
    auto mapping = canopen::PdoMapping::create(pdo.mapping);
    if (!mapping) throw std::runtime_error(device_.name + " " + pdo.name + ": " + mapping.error().message);
    if (!pdo.enabled) continue;
    canopen::PdoBinding binding(std::move(*mapping), image_);
    if (pdo.direction == PdoDirection::tx) {
      const auto* b = &tpdo_bindings_.emplace_back(std::move(binding));
      tpdos_.push_back(std::make_unique<canopen::PdoTransmitter>(
          loop_, canopen::PdoTransmitter::Settings{pdo.can_id, pdo.extended, pdo.transmission_type, pdo.inhibit, pdo.event_timer},
          [this, b](can::CanFrame& f) { f.len = b->pack_from(image_, std::span<std::uint8_t, 8>(f.data)); },
          [this] { return nmt_.state() == NmtState::operational; }));
    } else {
      rpdos_.push_back({&pdo, std::move(binding), std::nullopt});
    }
  }
  for (std::size_t i = 0; i < rpdos_.size(); ++i) {
    const auto handler = [this, i](const can::CanFrame& f) {
      if (nmt_.state() != NmtState::operational) return;
      Rpdo& r = rpdos_[i];
      if (r.def->synchronous()) r.pending = f;
      else apply_rpdo(r, f);  // event-driven: takes effect at once
    };
    if (rpdos_[i].def->extended) loop_.on_extended_frame(rpdos_[i].def->can_id, handler);
    else loop_.on_frame(rpdos_[i].def->can_id, handler);
  }
  loop_.on_frame(canopen::cob::sync, [this](const can::CanFrame&) { on_sync(); });
  reset_application();
  link_dictionary();
}

void SawSimulator::link_dictionary() {
  auto& od = sdo_.dictionary();
  // Every profile object the simulation computes with is kept in the image; an SDO write of one
  // of them changes the simulation at once.
  for (const auto& o : profile_.objects) {
    const std::size_t s = image_.find(o.index, o.sub);
    if (s == canopen::ProcessImage::npos || !o.writable()) continue;
    (void)od.set_on_write(o.index, o.sub, [this, s](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
      std::uint64_t raw = 0;
      for (std::size_t i = 0; i < v.size() && i < 8; ++i) raw |= std::uint64_t{v[i]} << (8 * i);
      image_.set(s, raw);
      return std::nullopt;
    });
  }
  (void)od.set_on_write(0x1017, 0, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    nmt_.set_heartbeat_period(std::chrono::milliseconds(v[0] | v[1] << 8));
    return std::nullopt;
  });
  publish_to_dictionary();
}

void SawSimulator::publish_to_dictionary() {
  auto& od = sdo_.dictionary();
  for (const auto& o : profile_.objects) {
    const std::size_t s = image_.find(o.index, o.sub);
    if (s == canopen::ProcessImage::npos) continue;
    const std::size_t n = canopen::bit_size(o.type) / 8;
    std::vector<std::uint8_t> bytes(n);
    for (std::size_t i = 0; i < n; ++i) bytes[i] = static_cast<std::uint8_t>(image_.get(s) >> (8 * i));
    (void)od.set(o.index, o.sub, std::move(bytes));
  }
}

std::size_t SawSimulator::slot(std::string_view object) {
  const auto* def = profile_.object(object);
  if (def == nullptr) throw std::runtime_error(device_.name + ": profile has no object " + std::string(object));
  return image_.slot(def->index, def->sub);
}

unsigned SawSimulator::bit(std::string_view set, std::string_view name) {
  const auto* s = profile_.bitset(set);
  const auto b = s != nullptr ? s->bit(name) : std::nullopt;
  if (!b) throw std::runtime_error(device_.name + ": profile has no bit " + std::string(set) + "." + std::string(name));
  return *b;
}

void SawSimulator::start() {
  spdlog::info("sim {}: saw node {} booting ({})", device_.name, device_.node_id, profile_.key());
  nmt_.boot();
}

void SawSimulator::reset_application() {
  for (auto slot : {control_word_, sync_speed_set_, length_set_, saw_counter_, status_word_}) image_.set(slot, 0);
  image_.set(speed_max_, static_cast<std::uint64_t>(device_.simulation.max_speed_m_per_min * 1000.0));  // mm/min
  speed_mm_per_min_ = 0;
  saw_counter_01mm_ = 0;
  program_was_on_ = false;
  last_change_bit_ = false;
  active_length_ = 0;
  pending_length_.reset();
}

void SawSimulator::on_sync() {
  const auto now = Clock::now();
  const double dt = last_sync_ ? std::min(std::chrono::duration<double>(now - *last_sync_).count(), kMaxStep) : 0.0;
  last_sync_ = now;
  if (nmt_.state() != NmtState::operational) return;

  for (auto& r : rpdos_) {
    if (!r.pending) continue;
    apply_rpdo(r, *r.pending);
    r.pending.reset();
  }
  step(dt);
  publish_to_dictionary();
  for (auto& t : tpdos_) {
    t->on_sync();
    t->on_data();
  }
}

void SawSimulator::apply_rpdo(Rpdo& rpdo, const can::CanFrame& frame) {
  if (!rpdo.binding.unpack_into(frame.payload(), image_)) {
    if (short_rpdos_++ % 100 == 0) spdlog::warn("sim {}: {} shorter than its mapping ignored", device_.name, rpdo.def->name);
  }
}

void SawSimulator::step(double dt_s) {
  const auto now = Clock::now();
  const std::uint64_t cw = image_.get(control_word_);
  const bool program_on = ((cw >> cw_program_on_) & 1U) != 0;
  const bool change_bit = ((cw >> cw_change_of_length_) & 1U) != 0;

  // The line speed follows the sync speed set value (0.01 % of the maximum) along a ramp.
  const double max_mm_per_min = static_cast<double>(image_.get(speed_max_));  // 6006h, settable by SDO
  const double target = static_cast<double>(image_.get(sync_speed_set_)) / 10000.0 * max_mm_per_min;
  const double max_delta = device_.simulation.acceleration_m_per_min_s * 1000.0 * dt_s;
  speed_mm_per_min_ += std::clamp(target - speed_mm_per_min_, -max_delta, max_delta);
  const double travelled_mm = speed_mm_per_min_ / 60.0 * dt_s;
  pulses_ += travelled_mm / 1000.0 * device_.simulation.scaling_pulses_per_m;

  if (program_on) {
    if (!program_was_on_) {
      active_length_ = image_.get(length_set_);  // the program starts with the length in force
      pending_length_.reset();
      saw_counter_01mm_ = 0;
    } else if (change_bit != last_change_bit_) {
      pending_length_ = image_.get(length_set_);  // taken after the next cut (6020h bit c)
    }
    saw_counter_01mm_ += travelled_mm * 10.0;
    if (active_length_ > 0 && saw_counter_01mm_ >= static_cast<double>(active_length_)) {
      saw_counter_01mm_ -= static_cast<double>(active_length_);
      cutting_until_ = now + kCuttingPulse;
      if (pending_length_) active_length_ = *pending_length_;
      pending_length_.reset();
    }
  } else {
    saw_counter_01mm_ = 0;  // "saw program off: actual saw counter is reset and off"
  }
  program_was_on_ = program_on;
  last_change_bit_ = change_bit;

  std::uint64_t sw = 0;
  if (program_on) sw |= 1ULL << sw_ready_;
  if (now < cutting_until_) sw |= 1ULL << sw_cutting_;
  sw |= 1ULL << sw_program_enabled_;
  image_.set(status_word_, sw);
  image_.set(counter_value_, static_cast<std::uint64_t>(pulses_) & 0xFFFFFFFFULL);
  image_.set(saw_counter_, static_cast<std::uint64_t>(static_cast<std::int64_t>(saw_counter_01mm_)));
  image_.set(product_speed_, static_cast<std::uint64_t>(static_cast<std::int64_t>(speed_mm_per_min_)));
}

}  // namespace lb::sim
