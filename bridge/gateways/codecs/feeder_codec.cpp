#include "gateways/codecs/feeder_codec.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "gateways/codecs/pdo_binding.hpp"
#include "gateways/codecs/profile_lookup.hpp"

namespace lb::gateways {

namespace msg = linebridge_msgs::msg;
using profiles::BitField;
using profiles::ObjectDef;

namespace {

// Each name once, in code order (several codes may share a name).
std::string names_of(const profiles::ValueTable& table) {
  std::vector<std::string_view> seen;
  std::string out;
  for (const auto& r : table.ranges) {
    if (std::find(seen.begin(), seen.end(), r.name) != seen.end()) continue;
    seen.push_back(r.name);
    out += (out.empty() ? "" : ", ") + r.name;
  }
  return out;
}

// CiA 414-2 5.2.16: the parameter range depends on the test (the profile's table names only the
// codes). 0 stops a motor or pin test.
Result<std::uint64_t> test_parameter(const std::string& test, std::uint8_t parameter) {
  const auto within = [&](unsigned lo, unsigned hi, const char* unit) -> Result<std::uint64_t> {
    if (parameter == 0 || (parameter >= lo && parameter <= hi)) return std::uint64_t{parameter};
    return make_error(fmt::format("{} parameter {} is outside 0 (stop) or {}..{}{}", test, parameter, lo, hi, unit));
  };
  if (test == "motor_test") return within(5, 100, " Hz");
  if (test == "pin_test") return within(1, 20, " Hz");
  if (test == "strobo_function") {
    if (parameter <= 1) return std::uint64_t{parameter};
    return make_error(fmt::format("strobo_function parameter {} is neither 0 (off) nor 1 (on)", parameter));
  }
  return std::uint64_t{0};  // no_test: "can be any value and must be ignored"; sent as 0
}

}  // namespace

FeederCodec::FeederCodec(const profiles::Profile& profile, std::span<const profiles::DevicePdo> pdos,
                         bool rpdos_received)
    : profile_(profile) {
  status_ = &object("feeder_status_1").values;
  error_condition_ = &object("feeder_error_condition_1").values;
  control_box_error_ = &object("feeder_control_box_error_condition").values;
  functions_ = &bitset("feeder_functions");
  unwinding_ = &bitset("feeder_unwinding_time");
  weft_filling_ = &bitset("global_weft_filling_parameter");
  test_ = &bitset("feeder_test");
  trigger_bits_ = &bitset("trigger_sources_selected");
  supported_ = &object("trigger_sources_supported");
  selected_ = &object("trigger_sources_selected");
  for (const auto* name : {"coil_unwinding_time", "winding_number", "feeder_selected"}) (void)field(*unwinding_, name);
  for (const auto* name : {"maximum_speed", "loom_width"}) (void)field(*weft_filling_, name);
  for (const auto* name : {"test_code", "test_parameter"}) (void)field(*test_, name);

  unwinding_time_ = bind("feeder_unwinding_time");
  loom_status_ = bind("loom_status");
  weft_filling_word_ = bind("global_weft_filling_parameter");
  trigger_signal_ = bind("trigger_signal");
  for (std::size_t i = 0; i < picks_.size(); ++i) picks_[i] = bind("pick_insertion_" + std::to_string(i + 1));
  for (std::size_t i = 0; i < outputs_.size(); ++i) outputs_[i] = bind("digital_outputs_" + std::to_string(i + 1));

  others_.emplace(profile_, image_, rpdos_received);
  defs_.assign(pdos.begin(), pdos.end());
  for (const auto& pdo : defs_) pdos_.push_back({&pdo, bind_line_pdo(profile_, image_, pdo, *others_, pdos_.size())});
}

Result<void> FeederCodec::use_pdo(std::size_t pdo, const profiles::DevicePdo& actual) {
  return use_device_pdo(profile_, image_, defs_[pdo], pdos_[pdo].binding, actual, *others_, pdo);
}

const ObjectDef& FeederCodec::object(std::string_view name) const { return required_object(profile_, name); }

const profiles::BitSet& FeederCodec::bitset(std::string_view name) const { return required_bitset(profile_, name); }

const BitField& FeederCodec::field(const profiles::BitSet& set, std::string_view name) const {
  const auto* f = set.field(name);
  if (f == nullptr)
    throw std::runtime_error("profile " + profile_.key() + ": bit set " + set.name + " has no field '" +
                             std::string(name) + "'");
  return *f;
}

FeederCodec::Object FeederCodec::bind(std::string_view name) {
  const auto& def = object(name);
  return {&def, image_.slot(def.index, def.sub)};
}

Result<void> FeederCodec::receive(std::size_t pdo, std::span<const std::uint8_t> payload) {
  auto r = pdos_[pdo].binding.unpack_into(payload, image_);
  if (r && pdos_[pdo].def->direction == profiles::PdoDirection::rx) loom_seen_ = true;
  return r;
}

bool FeederCodec::carries(std::size_t pdo, std::uint16_t index) const {
  const auto entries = pdos_[pdo].binding.mapping().entries();
  return std::any_of(entries.begin(), entries.end(), [index](const canopen::PdoEntry& e) { return e.index == index; });
}

msg::FeederCode FeederCodec::code(const profiles::ValueTable& table, std::uint64_t raw) {
  msg::FeederCode c;
  c.raw(static_cast<std::uint8_t>(raw));
  const auto name = table.name(raw);
  c.valid(table.valid(raw));
  c.name(name ? std::string(*name) : std::string());
  return c;
}

msg::FeederFunctions FeederCodec::functions(std::uint32_t raw) const {
  using Accessor = msg::FeederFunction& (msg::FeederFunctions::*)();
  static constexpr std::pair<std::string_view, Accessor> kFields[] = {
      {"brush_release", &msg::FeederFunctions::brush_release},
      {"winding_direction", &msg::FeederFunctions::winding_direction},
      {"angle_trigger_monitoring", &msg::FeederFunctions::angle_trigger_monitoring},
      {"yarn_break_sensor", &msg::FeederFunctions::yarn_break_sensor},
      {"input_knot_detection_sensor", &msg::FeederFunctions::input_knot_detection_sensor},
      {"yarn_quality_sensor", &msg::FeederFunctions::yarn_quality_sensor},
      {"rotation_direction_sensor", &msg::FeederFunctions::rotation_direction_sensor},
      {"tks_sensor", &msg::FeederFunctions::tks_sensor}};
  msg::FeederFunctions out;
  out.raw(raw);
  for (const auto& [name, get] : kFields) {
    const auto* f = functions_->field(name);
    if (f == nullptr) continue;  // an override without this field: stays "not read" (all zero, invalid)
    const std::uint64_t v = f->extract(raw);
    const auto state = f->values.name(v);
    msg::FeederFunction& fn = (out.*get)();
    fn.raw(static_cast<std::uint8_t>(v));
    fn.valid(state.has_value());
    fn.state(state ? std::string(*state) : std::string());
    fn.available(state.has_value() && *state != "not_available");
    fn.on(v == 0b11);
  }
  return out;
}

msg::PickInsertion FeederCodec::pick(std::uint8_t raw) const {
  msg::PickInsertion p;
  p.raw(raw);
  const auto kind = picks_[0].def->values.name(raw);
  p.valid(kind.has_value());
  if (!kind) return p;  // reserved or outside the table's rows: no colours guessed
  p.kind(std::string(*kind));
  const std::uint8_t high = raw >> 4, low = raw & 0x0F;
  if (*kind == "single_pick")
    p.colours({static_cast<std::uint8_t>(raw == 0x10 ? 16 : low)});
  else if (*kind == "double_pick")
    p.colours({high, low});
  else if (*kind == "triple_pick")
    p.colours({high, static_cast<std::uint8_t>(high + 2), static_cast<std::uint8_t>(high + 4)});
  return p;
}

msg::FeederUnwinding FeederCodec::unwinding(std::uint32_t raw) const {
  const auto& feeder = *unwinding_->field("feeder_selected");
  const auto& winding = *unwinding_->field("winding_number");
  const auto& time = *unwinding_->field("coil_unwinding_time");
  msg::FeederUnwinding u;
  u.raw(raw);
  u.feeder_selected(static_cast<std::uint8_t>(feeder.extract(raw)));
  u.winding_number(static_cast<std::uint8_t>(winding.extract(raw)));
  u.coil_unwinding_time_ms(time.to_engineering(time.extract(raw)));
  u.in_range(feeder.in_range(feeder.extract(raw)) && winding.in_range(winding.extract(raw)) &&
             time.in_range(time.extract(raw)));
  return u;
}

msg::FeederUnwinding FeederCodec::last_unwinding() const {
  return unwinding(static_cast<std::uint32_t>(image_.get(unwinding_time_.slot)));
}

void FeederCodec::fill_loom(msg::LoomSide& loom, bool outputs_in_use) const {
  loom.seen(loom_seen_);
  loom.loom_status(code(loom_status_.def->values, image_.get(loom_status_.slot)));
  const std::uint64_t weft = image_.get(weft_filling_word_.slot);
  const auto& speed = *weft_filling_->field("maximum_speed");
  const auto& width = *weft_filling_->field("loom_width");
  loom.weft_filling_raw(static_cast<std::uint32_t>(weft));
  loom.maximum_speed_per_min(static_cast<std::uint16_t>(speed.extract(weft)));
  loom.loom_width_m(width.to_engineering(width.extract(weft)));
  loom.trigger_signal(code(trigger_signal_.def->values, image_.get(trigger_signal_.slot)));
  loom.pick_insertion().clear();
  for (const auto& p : picks_) loom.pick_insertion().push_back(pick(static_cast<std::uint8_t>(image_.get(p.slot))));
  loom.digital_outputs().clear();
  if (outputs_in_use) {
    for (const auto& o : outputs_) loom.digital_outputs().push_back(static_cast<std::uint8_t>(image_.get(o.slot)));
  }
}

std::uint32_t FeederCodec::ff10_bitmap(const std::array<std::uint8_t, 5>& m) {
  return std::uint32_t{m[0]} | std::uint32_t{m[1]} << 8 | std::uint32_t{m[2]} << 16 | std::uint32_t{m[3]} << 24;
}

Result<FeederCodec::Write> FeederCodec::checked(const ObjectDef& object, std::uint64_t raw) {
  if (!object.writable()) {
    return make_error(object.name + " is " + std::string(profiles::to_string(object.access)) + ", not writable");
  }
  if (raw > canopen::type_max(object.type)) {
    return make_error(fmt::format("{} value {} does not fit {}", object.name, raw, canopen::to_string(object.type)));
  }
  if (auto r = object.check_raw(static_cast<std::int64_t>(raw)); !r) return r.error();
  if (!object.values.valid(raw)) {
    return make_error(
        fmt::format("{} code {:02X}h is reserved or undefined ({})", object.name, raw, names_of(object.values)));
  }
  return Write{&object, raw};
}

Result<const ObjectDef*> FeederCodec::per_feeder(std::string_view array, unsigned feeder,
                                                 std::optional<unsigned> count) const {
  if (feeder < 1 || feeder > kMaxFeeders)
    return make_error(fmt::format("feeder {} is outside 1..{}", feeder, kMaxFeeders));
  if (count && feeder > *count)
    return make_error(fmt::format("feeder {}: the control box reports {} feeder(s)", feeder, *count));
  const auto* def = profile_.object(std::string(array) + "_" + std::to_string(feeder));
  if (def == nullptr)
    return make_error(fmt::format("profile {} has no {} for feeder {}", profile_.key(), array, feeder));
  return def;
}

Result<FeederCodec::Write> FeederCodec::command(unsigned feeder, const std::string& name,
                                                std::uint8_t manufacturer_code, std::optional<unsigned> count) const {
  auto obj = per_feeder("feeder_command", feeder, count);
  if (!obj) return obj.error();
  const auto& table = (*obj)->values;
  if (name == "manufacturer_specific") {
    if (table.name(manufacturer_code) != "manufacturer_specific") {
      return make_error(
          fmt::format("manufacturer_code {:02X}h is not a manufacturer-specific command code", manufacturer_code));
    }
    return checked(**obj, manufacturer_code);
  }
  const auto code = table.code(name);
  if (!code) return make_error("unknown feeder command '" + name + "' (" + names_of(table) + ")");
  return checked(**obj, *code);
}

Result<FeederCodec::Write> FeederCodec::test(unsigned feeder, const std::string& name, std::uint8_t parameter,
                                             std::optional<unsigned> count) const {
  auto obj = per_feeder("feeder_test", feeder, count);
  if (!obj) return obj.error();
  const auto& code_field = *test_->field("test_code");
  const auto code = code_field.values.code(name);
  if (!code) return make_error("unknown feeder test '" + name + "' (" + names_of(code_field.values) + ")");
  auto param = test_parameter(name, parameter);
  if (!param) return param.error();
  return checked(**obj, code_field.insert(test_->field("test_parameter")->insert(0, *param), *code));
}

Result<const ObjectDef*> FeederCodec::functions_object(unsigned feeder, std::optional<unsigned> count) const {
  auto obj = per_feeder("feeder_functions", feeder, count);
  if (!obj) return obj.error();
  if (!(*obj)->readable() || !(*obj)->writable()) return make_error((*obj)->name + " is not read-write");
  return obj;
}

Result<std::uint64_t> FeederCodec::merge_functions(std::uint64_t current,
                                                   const std::vector<FunctionSetting>& settings) const {
  if (settings.empty()) return make_error("no function to set");
  std::uint64_t word = current;
  for (const auto& s : settings) {
    const BitField* f = functions_->field(s.function);
    if (f == nullptr || f->values.empty()) {
      std::string known;
      for (const auto& b : functions_->bits) known += (known.empty() ? "" : ", ") + b.name;
      return make_error("unknown feeder function '" + s.function + "' (" + known + ")");
    }
    const auto code = f->values.code(s.state);
    if (!code || s.state == "not_available") {
      std::string states;
      for (const auto& r : f->values.ranges) {
        if (r.name != "not_available") states += (states.empty() ? "" : ", ") + r.name;
      }
      return make_error(s.function + ": unknown state '" + s.state + "' (" + states + ")");
    }
    // "Only those functions and sensors that are marked as supported can be changed."
    const auto now = f->values.name(f->extract(current));
    if (!now || *now == "not_available") {
      return make_error(s.function + " is not available on this feeder (6001h reports " +
                        (now ? std::string(*now) : fmt::format("undefined code {:02b}b", f->extract(current))) + ")");
    }
    word = f->insert(word, *code);
  }
  return word;
}

Result<FeederCodec::Write> FeederCodec::number_assignment(unsigned feeder, std::uint8_t number,
                                                          std::optional<unsigned> count) const {
  auto obj = per_feeder("system_feeder_number_assignment", feeder, count);
  if (!obj) return obj.error();
  return checked(**obj, number);
}

Result<FeederCodec::Write> FeederCodec::color_assignment(unsigned feeder, std::uint8_t color,
                                                         std::optional<unsigned> count) const {
  auto obj = per_feeder("feeder_color_assignment", feeder, count);
  if (!obj) return obj.error();
  return checked(**obj, color);
}

Result<FeederCodec::Write> FeederCodec::weft_insertion_type(const std::string& name) const {
  const auto& obj = object("weft_insertion_type_parameter");
  const auto code = obj.values.code(name);
  if (!code) return make_error("unknown weft insertion type '" + name + "' (" + names_of(obj.values) + ")");
  return checked(obj, *code);
}

Result<FeederCodec::Write> FeederCodec::trigger_sources(const std::vector<std::string>& selected,
                                                        std::uint64_t supported) const {
  std::uint64_t raw = 0;
  for (const auto& name : selected) {
    const auto bit = trigger_bits_->bit(name);
    if (!bit) {
      std::string known;
      for (const auto& b : trigger_bits_->bits) known += (known.empty() ? "" : ", ") + b.name;
      return make_error("unknown trigger source '" + name + "' (" + known + ")");
    }
    if (((supported >> *bit) & 1U) == 0) {
      return make_error(
          fmt::format("trigger source {} is not supported by the device (6005h sub 1 = {:04X}h)", name, supported));
    }
    raw |= std::uint64_t{1} << *bit;
  }
  return checked(*selected_, raw);
}

Result<FeederCodec::RawLoom> FeederCodec::validate(const msg::LoomSetpoint& sp) const {
  RawLoom raw;
  if (!sp.loom_status().empty()) {
    const auto code = loom_status_.def->values.code(sp.loom_status());
    if (!code)
      return make_error("unknown loom_status '" + sp.loom_status() + "' (" + names_of(loom_status_.def->values) + ")");
    const auto& speed = *weft_filling_->field("maximum_speed");
    const auto& width = *weft_filling_->field("loom_width");
    if (!speed.in_range(sp.maximum_speed_per_min())) {
      return make_error(
          fmt::format("maximum_speed_per_min {} is outside the field's range", sp.maximum_speed_per_min()));
    }
    // Metres to the field's raw unit (cm): the exact inverse of the scale keeps 1.905 m at 190.5.
    const double cm = std::round(sp.loom_width_m() * std::round(1.0 / width.scale));
    if (!std::isfinite(cm) || cm < 0 || cm > static_cast<double>(width.mask() >> width.bit) ||
        !width.in_range(static_cast<std::uint64_t>(cm))) {
      return make_error(fmt::format("loom_width_m {} is outside 0..{} m", sp.loom_width_m(),
                                    width.to_engineering(width.mask() >> width.bit)));
    }
    auto status = checked(*loom_status_.def, *code);
    if (!status) return status.error();
    auto weft = checked(*weft_filling_word_.def,
                        width.insert(speed.insert(0, sp.maximum_speed_per_min()), static_cast<std::uint64_t>(cm)));
    if (!weft) return weft.error();
    raw.loom_status = status->raw;
    raw.weft_filling = weft->raw;
  }
  if (!sp.trigger_signal().empty()) {
    const auto code = trigger_signal_.def->values.code(sp.trigger_signal());
    if (!code)
      return make_error("unknown trigger_signal '" + sp.trigger_signal() + "' (" +
                        names_of(trigger_signal_.def->values) + ")");
    auto t = checked(*trigger_signal_.def, *code);
    if (!t) return t.error();
    raw.trigger = t->raw;
  }
  if (!sp.pick_insertion().empty()) {
    if (sp.pick_insertion().size() != picks_.size()) {
      return make_error(fmt::format("pick_insertion needs exactly {} codes (the next five picks), got {}",
                                    picks_.size(), sp.pick_insertion().size()));
    }
    std::array<std::uint64_t, 5> codes{};
    for (std::size_t i = 0; i < picks_.size(); ++i) {
      auto p = checked(*picks_[i].def, sp.pick_insertion()[i]);
      if (!p) return make_error(fmt::format("pick_insertion[{}]: {}", i, p.error().message));
      codes[i] = p->raw;
    }
    raw.picks = codes;
  }
  if (sp.digital_outputs().size() > outputs_.size()) {
    return make_error(fmt::format("digital_outputs has {} groups; 600Dh has {} (sub 1..{})",
                                  sp.digital_outputs().size(), outputs_.size(), outputs_.size()));
  }
  for (std::size_t i = 0; i < sp.digital_outputs().size(); ++i) {
    auto o = checked(*outputs_[i].def, sp.digital_outputs()[i]);
    if (!o) return make_error(fmt::format("digital_outputs[{}]: {}", i, o.error().message));
    raw.outputs.push_back(o->raw);
  }
  if (!raw.loom_status && !raw.trigger && !raw.picks && raw.outputs.empty()) {
    return make_error("nothing to send: give loom_status, trigger_signal, pick_insertion or digital_outputs");
  }
  return raw;
}

void FeederCodec::apply(const RawLoom& raw) {
  if (raw.loom_status) {
    image_.set(loom_status_.slot, *raw.loom_status);
    image_.set(weft_filling_word_.slot, raw.weft_filling);
  }
  if (raw.trigger) image_.set(trigger_signal_.slot, *raw.trigger);
  if (raw.picks) {
    for (std::size_t i = 0; i < picks_.size(); ++i) image_.set(picks_[i].slot, (*raw.picks)[i]);
  }
  for (std::size_t i = 0; i < raw.outputs.size(); ++i) image_.set(outputs_[i].slot, raw.outputs[i]);
  loom_seen_ = true;
}

}  // namespace lb::gateways
