#include "gateways/codecs/drive_image.hpp"

#include <stdexcept>

#include "canopen/data_type.hpp"
#include "gateways/codecs/pdo_binding.hpp"
#include "gateways/codecs/profile_lookup.hpp"

namespace lb::gateways {

namespace {

const profiles::PdoDef* profile_pdo(const profiles::Profile& profile, const std::string& name) {
  for (const auto& p : profile.pdos) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

bool maps(const canopen::PdoMapping& mapping, const profiles::ObjectDef& object) {
  for (const auto& e : mapping.entries()) {
    if (e.index == object.index && e.sub == object.sub) return true;
  }
  return false;
}

// The bits after the mapped objects, LSB first as CiA 301 packs them; nullopt when the frame ends
// before them. Counted from the device's mapping, so a mapping override moves the word with it.
std::optional<std::uint64_t> trailing(std::span<const std::uint8_t> payload, unsigned first, unsigned bits) {
  if (bits == 0 || bits > 64 || payload.size() * 8 < first + bits) return std::nullopt;
  std::uint64_t value = 0;
  for (unsigned i = 0; i < bits; ++i) {
    const unsigned at = first + i;
    if (((payload[at / 8] >> (at % 8)) & 1U) != 0) value |= std::uint64_t{1} << i;
  }
  return value;
}

}  // namespace

DriveImage::DriveImage(const profiles::Profile& profile, std::span<const profiles::DevicePdo> pdos,
                       std::string_view device, SetEchoMonitor::Settings echo, bool rpdos_received)
    : profile_(profile), echo_(echo) {
  const std::string d(device);
  status_word_ = bind("status_word");
  control_word_ = bind("control_word");
  speed_actual_ = bind(d + "_speed_actual_value");
  load_actual_ = bind(d + "_load_actual_value");
  speed_echo_ = bind(d + "_speed_set_echo");
  product_speed_ = bind("product_speed");
  speed_set_ = bind(d + "_speed_set_value");
  const auto& cw = bitset("control_word");
  bit_extruder_running_ = required_bit(profile_, cw, "extruder_running");

  others_.emplace(profile_, image_, rpdos_received);
  defs_.assign(pdos.begin(), pdos.end());
  for (const auto& pdo : defs_) {
    Pdo p{&pdo, bind_line_pdo(profile_, image_, pdo, *others_, pdos_.size()), std::nullopt, false};
    p.carries_echo = pdo.direction == profiles::PdoDirection::tx && maps(p.binding.mapping(), *speed_echo_.def);
    const auto* def = profile_pdo(profile_, pdo.name);
    if (def != nullptr && pdo.direction == profiles::PdoDirection::tx) p.manufacturer_data = def->manufacturer_data;
    pdos_.push_back(std::move(p));
  }
}

Result<void> DriveImage::use_pdo(std::size_t pdo, const profiles::DevicePdo& actual) {
  auto& p = pdos_[pdo];
  if (auto r = use_device_pdo(profile_, image_, defs_[pdo], p.binding, actual, *others_, pdo); !r) return r;
  p.carries_echo = actual.direction == profiles::PdoDirection::tx && maps(p.binding.mapping(), *speed_echo_.def);
  return {};
}

DriveImage::Object DriveImage::bind(const std::string& name) {
  const auto& def = required_object(profile_, name);
  return {&def, image_.slot(def.index, def.sub)};
}

const profiles::BitSet& DriveImage::bitset(std::string_view name) const { return required_bitset(profile_, name); }

std::int64_t DriveImage::signed_raw(const Object& o) const {
  const std::uint64_t raw = image_.get(o.slot);
  const unsigned bits = canopen::bit_size(o.def->type);
  return canopen::is_signed_integer(o.def->type) ? canopen::sign_extend(raw, bits) : static_cast<std::int64_t>(raw);
}

Result<void> DriveImage::receive(std::size_t pdo, std::span<const std::uint8_t> payload) {
  const Pdo& p = pdos_[pdo];
  if (auto r = p.binding.unpack_into(payload, image_); !r) return r;
  if (p.manufacturer_data) {
    const auto word = trailing(payload, p.binding.mapping().total_bits(), p.manufacturer_data->bits);
    manufacturer_status_word_ = word ? std::optional<std::uint16_t>(static_cast<std::uint16_t>(*word)) : std::nullopt;
  }
  if (p.carries_echo) echo_.observe(signed_raw(speed_set_), signed_raw(speed_echo_));
  return {};
}

Result<DriveImage::RawSetpoint> DriveImage::validate(bool extruder_running, double speed_set_percent) const {
  auto speed = speed_set_.def->to_raw(speed_set_percent);
  if (!speed) return make_error("speed_set_percent: " + speed.error().message);
  return RawSetpoint{extruder_running, *speed};
}

void DriveImage::apply(const RawSetpoint& raw) {
  set_control_bit(bit_extruder_running_, raw.extruder_running);
  echo_.restart();  // a set value sent starts a new settling time
  image_.set(speed_set_.slot, raw.speed_set);
}

void DriveImage::set_control_bit(unsigned bit, bool on) {
  const std::uint64_t cw = image_.get(control_word_.slot);
  image_.set(control_word_.slot, on ? cw | (1ULL << bit) : cw & ~(1ULL << bit));
}

}  // namespace lb::gateways
