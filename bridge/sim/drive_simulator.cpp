#include "sim/drive_simulator.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "canopen/data_type.hpp"

namespace lb::sim {

namespace {
// A cut request shows in the status word at least this long (CiA 420-1: request bits >= 100 ms).
constexpr auto kCutPulse = std::chrono::milliseconds(150);
constexpr double kCutEveryM = 1.0;         // corrugator: product between two cut requests
constexpr double kIdleLoadPercent = 15.0;  // a running drive's load at standstill
constexpr double kLoadPerSpeed = 0.6;      // load % per speed %

bool has(std::uint64_t word, std::optional<unsigned> bit) { return bit && ((word >> *bit) & 1U) != 0; }
std::uint64_t flag(bool on, std::optional<unsigned> bit) { return on && bit ? std::uint64_t{1} << *bit : 0; }
std::uint64_t raw16(double value) {
  return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::lround(value))) & 0xFFFF;
}

std::string drive_name(const profiles::Profile& profile) {
  const auto* cw = profile.bitset("control_word");
  if (cw != nullptr) {
    for (const auto& b : cw->bits) {
      if (b.bit == 0 && b.width == 1 && b.name.ends_with("_stop")) return b.name.substr(0, b.name.size() - 5);
    }
  }
  return "drive";
}
}  // namespace

DriveSimulator::DriveSimulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device,
                               const profiles::Profile& profile)
    : device_(device),
      profile_(profile),
      node_(loop, device, profile, {[this] { reset(); }, [this](double dt) { step(dt); }, {}, {}}) {
  const std::string d = profile_.device;  // the type's name: the prefix of its speed and load objects
  status_word_ = node_.slot("status_word");
  control_word_ = node_.slot("control_word");
  speed_actual_ = node_.slot(d + "_speed_actual_value");
  speed_set_ = node_.slot(d + "_speed_set_value");
  speed_echo_ = node_.slot(d + "_speed_set_echo");
  speed_set_max_ = node_.slot(d + "_speed_set_maximum");
  speed_real_max_ = node_.slot(d + "_speed_real_maximum");
  load_actual_ = node_.slot(d + "_load_actual_value");
  product_speed_ = node_.slot("product_speed");
  scaling_factor_ = node_.slot("scaling_factor");
  configuration_word_ = node_.slot("configuration_word");

  // What the type calls its drive ("motor" on a puller, "drive" on a corrugator): the name of
  // control word bit 0, "<drive>_stop" on every CiA 420 drive.
  const std::string drive = drive_name(profile_);
  drive_ = make_switch(drive + "_start", drive + "_stop", drive + "_running", drive + "_ready_to_start");
  clamp_ = make_switch("clamp_close", "clamp_open", "clamp_closed", "");
  for (int i = 0; i < 3; ++i) {
    const std::string f = "f" + std::to_string(i + 1);
    functions_[i] = make_switch(f + "_start", f + "_stop", f + "_running", f + "_ready");
  }
  if (!drive_.on_button || !drive_.off_button || !drive_.running_bit) {
    throw std::runtime_error(device_.name + ": profile " + profile_.key() + " has no " + drive +
                             " start/stop/running bits");
  }
  sw_reverse_ = node_.bit("status_word", "reverse_direction");
  sw_master_extruder_enabled_ = node_.bit("status_word", "master_extruder_enabled");
  sw_cut_pulse_ = node_.bit("status_word", "start_cut_pulse");
  if (const auto* sw = profile_.bitset("status_word"); sw != nullptr) {
    if (const auto* mode = sw->field("speed_set_mode"); mode != nullptr) {
      mode_mask_ = mode->mask();
      if (auto c = mode->values.code("remote")) mode_remote_ = mode->insert(0, *c);
      if (auto c = mode->values.code("local")) mode_local_ = mode->insert(0, *c);
    }
  }
  add_local_objects();
}

DriveSimulator::Switch DriveSimulator::make_switch(const std::string& on, const std::string& off,
                                                   const std::string& running, const std::string& ready) const {
  Switch s;
  s.on_button = node_.bit("control_word", on);
  s.off_button = node_.bit("control_word", off);
  s.running_bit = node_.bit("status_word", running);
  if (!ready.empty()) s.ready_bit = node_.bit("status_word", ready);
  return s;
}

void DriveSimulator::add_local_objects() {
  local_mode_ = node_.add_object(kLocalModeIndex, canopen::DataType::unsigned8, canopen::ObjectAccess::rw, 0, 1);
  local_speed_ = node_.add_object(kLocalSpeedIndex, canopen::DataType::integer16, canopen::ObjectAccess::rw, -10000,
                                  10000);
  node_.check_writes(kLocalModeIndex, 0, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    spdlog::info("sim {}: {} mode", device_.name, v[0] != 0 ? "local" : "remote");
    return std::nullopt;
  });
}

void DriveSimulator::start() { node_.boot(); }

void DriveSimulator::reset() {
  auto& image = node_.image();
  const auto max_mm_per_min = static_cast<std::uint64_t>(std::llround(device_.simulation.max_speed_m_per_min * 1000.0));
  image.set(speed_real_max_, max_mm_per_min);
  image.set(speed_set_max_, max_mm_per_min);
  image.set(scaling_factor_, device_.simulation.scaling_pulses_per_m);
  // The simulated device has every function its configuration word can name.
  std::uint64_t config = 0;
  if (const auto* cfg = profile_.bitset("configuration_word"); cfg != nullptr) {
    for (const auto& b : cfg->bits) config |= b.mask();
  }
  image.set(configuration_word_, config);
  drive_.running = clamp_.running = false;
  for (auto& f : functions_) f.running = false;
  last_cw_ = 0;
  speed_percent_ = 0;
  product_since_cut_m_ = 0;
  step(0.0);  // status, echo and values consistent before the first SYNC
}

void DriveSimulator::operate(Switch& s, std::uint64_t cw) const {
  // Stop is start prevention: while it is held the switch cannot start.
  if (has(cw, s.off_button))
    s.running = false;
  else if (has(cw, s.on_button) && !has(last_cw_, s.on_button))
    s.running = true;
}

void DriveSimulator::step(double dt_s) {
  auto& image = node_.image();
  const std::uint64_t cw = image.get(control_word_);
  operate(drive_, cw);
  operate(clamp_, cw);
  for (auto& f : functions_) operate(f, cw);
  last_cw_ = cw;

  // The speed ramps to the set value in force (remote: 6002h, local: 2101h) while the drive runs.
  const bool local = image.get(local_mode_) != 0;
  const std::int64_t set = canopen::sign_extend(image.get(local ? local_speed_ : speed_set_), 16);
  const double target = drive_.running ? static_cast<double>(set) / 100.0 : 0.0;
  const double max_mm_per_min = static_cast<double>(image.get(speed_set_max_));  // 6003h, settable by SDO
  const double max_delta = max_mm_per_min > 0
                               ? device_.simulation.acceleration_m_per_min_s * 1000.0 / max_mm_per_min * 100.0 * dt_s
                               : 100.0;
  speed_percent_ += std::clamp(target - speed_percent_, -max_delta, max_delta);
  const double product_mm_per_min = speed_percent_ / 100.0 * max_mm_per_min;
  const double load = drive_.running ? kIdleLoadPercent + kLoadPerSpeed * std::abs(speed_percent_) : 0.0;

  product_since_cut_m_ += std::abs(product_mm_per_min) / 1000.0 / 60.0 * dt_s;
  const auto now = Clock::now();
  if (sw_cut_pulse_ && product_since_cut_m_ >= kCutEveryM) {
    product_since_cut_m_ -= kCutEveryM;
    cut_pulse_until_ = now + kCutPulse;
  }

  std::uint64_t sw = flag(drive_.running, drive_.running_bit) | flag(!has(cw, drive_.off_button), drive_.ready_bit) |
                     flag(clamp_.running, clamp_.running_bit) | flag(speed_percent_ < 0, sw_reverse_) |
                     flag(drive_.running, sw_master_extruder_enabled_) | flag(now < cut_pulse_until_, sw_cut_pulse_);
  for (const auto& f : functions_) sw |= flag(f.running, f.running_bit) | flag(!has(cw, f.off_button), f.ready_bit);
  const auto mode = local ? mode_local_ : mode_remote_;
  if (mode) sw = (sw & ~mode_mask_) | *mode;

  image.set(status_word_, sw);
  image.set(speed_actual_, raw16(speed_percent_ * 100.0));
  image.set(load_actual_, raw16(load * 100.0));
  image.set(speed_echo_, static_cast<std::uint64_t>(set) & 0xFFFF);
  image.set(product_speed_, static_cast<std::uint64_t>(std::llround(product_mm_per_min * 10.0)) & 0xFFFF'FFFFULL);
}

}  // namespace lb::sim
