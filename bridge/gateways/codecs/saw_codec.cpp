#include "gateways/codecs/saw_codec.hpp"

#include <stdexcept>

#include "gateways/codecs/pdo_binding.hpp"
#include "gateways/codecs/profile_lookup.hpp"
#include "msgs/word_bindings.hpp"

namespace lb::gateways {

namespace msg = linebridge_msgs::msg;

SawCodec::SawCodec(const profiles::Profile& profile, std::span<const profiles::DevicePdo> pdos, bool rpdos_received)
    : profile_(profile) {
  status_word_ = bind("status_word");
  control_word_ = bind("control_word");
  counter_value_ = bind("counter_value");
  saw_counter_ = bind("actual_saw_counter");
  product_speed_ = bind("product_speed");
  sync_speed_set_ = bind("saw_sync_speed_set_value");
  length_set_ = bind("product_length_set_value");

  const auto& sw = bitset("status_word");
  const auto& cw = bitset("control_word");
  // The word fields by name, generated from saw.idl (idl/word_bindings.cmake) and held against
  // the profile by lb-check-device-types at build time.
  using Binding = linebridge_msgs::bindings::Saw;
  status_bits_ = NamedBits<msg::SawStatusWord>(sw, Binding::status_flags);
  control_bits_ = NamedBits<msg::SawControlWord>(cw, Binding::control_flags);
  bit_program_on_ = required_bit(profile_, cw, "saw_program_on");
  bit_change_of_length_ = required_bit(profile_, cw, "change_of_length");
  bit_saw_cutting_ = required_bit(profile_, sw, "saw_cutting");
  bit_count_mode_ = cw.bit("count_mode");
  bit_wall_thickening_ = cw.bit("wall_thickening");

  others_.emplace(profile_, image_, rpdos_received);
  defs_.assign(pdos.begin(), pdos.end());
  for (const auto& pdo : defs_) pdos_.push_back({&pdo, bind_line_pdo(profile_, image_, pdo, *others_, pdos_.size())});
}

Result<void> SawCodec::use_pdo(std::size_t pdo, const profiles::DevicePdo& actual) {
  return use_device_pdo(profile_, image_, defs_[pdo], pdos_[pdo].binding, actual, *others_, pdo);
}

SawCodec::Object SawCodec::bind(std::string_view name) {
  const auto& def = required_object(profile_, name);
  return {&def, image_.slot(def.index, def.sub)};
}

const profiles::BitSet& SawCodec::bitset(std::string_view name) const { return required_bitset(profile_, name); }

void SawCodec::fill(msg::SawStatus& status) const {
  const std::uint64_t sw = image_.get(status_word_.slot);
  status.status_word().raw(static_cast<std::uint16_t>(sw));
  status_bits_.decode(sw, status.status_word());
  status.counter_value(static_cast<std::uint32_t>(image_.get(counter_value_.slot)));
  status.actual_saw_counter_m(saw_counter_.def->to_engineering(image_.get(saw_counter_.slot)));
  status.product_speed_m_per_min(product_speed_.def->to_engineering(image_.get(product_speed_.slot)));

  const std::uint64_t cw = image_.get(control_word_.slot);
  status.control_word().raw(static_cast<std::uint16_t>(cw));
  control_bits_.decode(cw, status.control_word());
  const bool corrugated = bit_count_mode_ && ((cw >> *bit_count_mode_) & 1U) != 0;
  status.control_word().count_mode(corrugated ? msg::CORRUGATED_PIPE : msg::SMOOTH_PIPE);
  status.sync_speed_set_percent(sync_speed_set_.def->to_engineering(image_.get(sync_speed_set_.slot)));
  status.product_length_set_m(length_set_.def->to_engineering(image_.get(length_set_.slot)));
  others_->fill(image_, status.other_values());
}

bool SawCodec::cutting() const { return ((image_.get(status_word_.slot) >> bit_saw_cutting_) & 1U) != 0; }

Result<SawCodec::RawSetpoint> SawCodec::validate(const msg::SawSetpoint& sp) const {
  if (sp.count_mode() != msg::SMOOTH_PIPE && sp.count_mode() != msg::CORRUGATED_PIPE) {
    return make_error("count_mode " + std::to_string(static_cast<int>(sp.count_mode())) + " is not a count mode");
  }
  RawSetpoint raw{sp.saw_program_on(), sp.wall_thickening(), sp.count_mode() == msg::CORRUGATED_PIPE, 0, 0};
  if (raw.corrugated && !bit_count_mode_) {
    return make_error("profile " + profile_.key() + " has no count mode bit: corrugated pipe mode is not available");
  }
  if (raw.wall_thickening && !bit_wall_thickening_) {
    return make_error("profile " + profile_.key() + " has no wall-thickening bit");
  }
  auto speed = sync_speed_set_.def->to_raw(sp.sync_speed_percent());
  if (!speed) return make_error("sync_speed_percent: " + speed.error().message);
  auto length = length_set_.def->to_raw(sp.product_length_m());
  if (!length) return make_error("product_length_m: " + length.error().message);
  raw.sync_speed = *speed;
  raw.product_length = *length;
  return raw;
}

void SawCodec::apply(const RawSetpoint& raw) {
  std::uint64_t cw = image_.get(control_word_.slot);
  const auto set_bit = [&cw](unsigned bit, bool on) { cw = on ? cw | (1ULL << bit) : cw & ~(1ULL << bit); };
  set_bit(bit_program_on_, raw.program_on);
  if (bit_wall_thickening_) set_bit(*bit_wall_thickening_, raw.wall_thickening);
  if (bit_count_mode_) set_bit(*bit_count_mode_, raw.corrugated);
  if (raw.product_length != image_.get(length_set_.slot)) cw ^= 1ULL << bit_change_of_length_;
  image_.set(control_word_.slot, cw);
  image_.set(sync_speed_set_.slot, raw.sync_speed);
  image_.set(length_set_.slot, raw.product_length);
}

}  // namespace lb::gateways

namespace lb::gateways {

void SawCodec::set_control_bit(unsigned bit, bool on) {
  const std::uint64_t cw = image_.get(control_word_.slot);
  image_.set(control_word_.slot, on ? cw | (1ULL << bit) : cw & ~(1ULL << bit));
}

}  // namespace lb::gateways
