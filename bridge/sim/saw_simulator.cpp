#include "sim/saw_simulator.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace lb::sim {

namespace {
// A cut shows in the status word at least this long (CiA 420-1: request bits >= 100 ms).
constexpr auto kCuttingPulse = std::chrono::milliseconds(150);
}  // namespace

SawSimulator::SawSimulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device,
                           const profiles::Profile& profile)
    : device_(device), node_(loop, device, profile, {[this] { reset(); }, [this](double dt) { step(dt); }, {}, {}}) {
  status_word_ = node_.slot("status_word");
  control_word_ = node_.slot("control_word");
  counter_value_ = node_.slot("counter_value");
  saw_counter_ = node_.slot("actual_saw_counter");
  product_speed_ = node_.slot("product_speed");
  sync_speed_set_ = node_.slot("saw_sync_speed_set_value");
  length_set_ = node_.slot("product_length_set_value");
  speed_max_ = node_.slot("saw_sync_speed_set_maximum");
  configuration_word_ = node_.slot("configuration_word");
  cw_program_on_ = required_bit("control_word", "saw_program_on");
  cw_change_of_length_ = required_bit("control_word", "change_of_length");
  sw_ready_ = required_bit("status_word", "saw_ready");
  sw_cutting_ = required_bit("status_word", "saw_cutting");
  sw_program_enabled_ = node_.bit("status_word", "saw_program_enabled").value_or(sw_ready_);
}

unsigned SawSimulator::required_bit(std::string_view set, std::string_view name) const {
  const auto b = node_.bit(set, name);
  if (!b) throw std::runtime_error(device_.name + ": profile has no bit " + std::string(set) + "." + std::string(name));
  return *b;
}

void SawSimulator::start() { node_.boot(); }

void SawSimulator::reset() {
  node_.image().set(speed_max_, static_cast<std::uint64_t>(device_.simulation.max_speed_m_per_min * 1000.0));  // mm/min
  // Its hardware: a measuring wheel, cut depth, early warning and groove counting where the
  // profile (version) names them; no height adjustment, no functions f1..f3, no corrugator cut
  // management.
  std::uint64_t config = 0;
  for (const auto* name : {"speed_measuring", "cut_depth", "early_warning", "groove_count_mode"}) {
    if (const auto bit = node_.bit("configuration_word", name)) config |= std::uint64_t{1} << *bit;
  }
  node_.image().set(configuration_word_, config);
  speed_mm_per_min_ = 0;
  saw_counter_01mm_ = 0;
  pulses_ = 0;
  cutting_until_ = {};
  program_was_on_ = false;
  last_change_bit_ = false;
  active_length_ = 0;
  pending_length_.reset();
}

void SawSimulator::step(double dt_s) {
  auto& image = node_.image();
  const auto now = Clock::now();
  const std::uint64_t cw = image.get(control_word_);
  const bool program_on = ((cw >> cw_program_on_) & 1U) != 0;
  const bool change_bit = ((cw >> cw_change_of_length_) & 1U) != 0;

  // The line speed follows the sync speed set value (0.01 % of the maximum) along a ramp.
  const double max_mm_per_min = static_cast<double>(image.get(speed_max_));  // 6006h, settable by SDO
  const double target = static_cast<double>(image.get(sync_speed_set_)) / 10000.0 * max_mm_per_min;
  const double max_delta = device_.simulation.acceleration_m_per_min_s * 1000.0 * dt_s;
  speed_mm_per_min_ += std::clamp(target - speed_mm_per_min_, -max_delta, max_delta);
  const double travelled_mm = speed_mm_per_min_ / 60.0 * dt_s;
  pulses_ += travelled_mm / 1000.0 * device_.simulation.scaling_pulses_per_m;

  if (program_on) {
    if (!program_was_on_) {
      active_length_ = image.get(length_set_);  // the program starts with the length in force
      pending_length_.reset();
      saw_counter_01mm_ = 0;
    } else if (change_bit != last_change_bit_) {
      pending_length_ = image.get(length_set_);  // taken after the next cut (6020h bit c)
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
  image.set(status_word_, sw);
  image.set(counter_value_, static_cast<std::uint64_t>(pulses_) & 0xFFFFFFFFULL);
  image.set(saw_counter_, static_cast<std::uint64_t>(static_cast<std::int64_t>(saw_counter_01mm_)));
  image.set(product_speed_, static_cast<std::uint64_t>(static_cast<std::int64_t>(speed_mm_per_min_)));
}

}  // namespace lb::sim
