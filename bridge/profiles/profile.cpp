#include "profiles/profile.hpp"

#include <cmath>
#include <string>

#include <fmt/format.h>

namespace lb::profiles {

std::string_view to_string(Access access) {
  switch (access) {
    case Access::ro: return "ro";
    case Access::wo: return "wo";
    case Access::rw: return "rw";
    case Access::const_: return "const";
  }
  return "?";
}

double ObjectDef::to_engineering(std::uint64_t raw) const {
  const unsigned bits = canopen::bit_size(type);
  const double value = canopen::is_signed_integer(type) ? static_cast<double>(canopen::sign_extend(raw, bits))
                                                        : static_cast<double>(raw);
  return value * scale;
}

Result<std::uint64_t> ObjectDef::check_raw(std::int64_t raw) const {
  const std::int64_t lo = min.value_or(canopen::type_min(type));
  const std::uint64_t type_hi = canopen::type_max(type);
  const bool above = max ? raw > *max : (raw > 0 && static_cast<std::uint64_t>(raw) > type_hi);
  if (raw < lo || above) {
    return make_error(fmt::format("{} raw value {} is outside {}..{}{}", name, raw, lo,
                                  max ? fmt::format("{}", *max) : fmt::format("{}", type_hi),
                                  unit.empty() ? "" : " (" + unit + ")"));
  }
  return static_cast<std::uint64_t>(raw);
}

Result<std::uint64_t> ObjectDef::to_raw(double engineering) const {
  if (!std::isfinite(engineering)) return make_error(name + ": value is not a finite number");
  // Scales such as 0.01 are not exact in binary: multiplying by the exact inverse (100) keeps a
  // value like 12.125 % at 1212.5 raw, which std::round then takes half away from zero.
  const double inverse = std::round(1.0 / scale);
  const bool exact_inverse = inverse >= 1.0 && std::abs(inverse * scale - 1.0) < 1e-12;
  const double raw = std::round(exact_inverse ? engineering * inverse : engineering / scale);
  const double lo = static_cast<double>(min.value_or(canopen::type_min(type)));
  const double hi = max ? static_cast<double>(*max) : static_cast<double>(canopen::type_max(type));
  if (raw < lo || raw > hi) {
    const std::string u = eng_unit.empty() ? "" : " " + eng_unit;
    return make_error(fmt::format("{} {}{} is out of range {}..{}{}", name, engineering, u, lo * scale, hi * scale, u));
  }
  if (raw >= 9.2e18) return static_cast<std::uint64_t>(raw);  // UNSIGNED64 beyond int64: range checked above
  return check_raw(static_cast<std::int64_t>(raw));
}

std::string_view to_string(PdoValidity validity) {
  switch (validity) {
    case PdoValidity::valid: return "valid";
    case PdoValidity::not_valid: return "not valid";
    case PdoValidity::either: return "valid or not valid";
  }
  return "?";
}

std::optional<std::string_view> ValueTable::name(std::uint64_t code) const {
  for (const auto& r : ranges) {
    if (code >= r.first && code <= r.last) return std::string_view(r.name);
  }
  return std::nullopt;
}

std::optional<std::uint64_t> ValueTable::code(std::string_view wanted) const {
  std::optional<std::uint64_t> found;
  for (const auto& r : ranges) {
    if (r.name != wanted) continue;
    if (r.first != r.last || found) return std::nullopt;  // several codes: none is "the" code
    found = r.first;
  }
  return found;
}

std::uint64_t BitField::mask() const {
  const std::uint64_t low = width >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << width) - 1;
  return bit >= 64 ? 0 : low << bit;
}

std::uint64_t BitField::insert(std::uint64_t word, std::uint64_t value) const {
  return (word & ~mask()) | ((value << bit) & mask());
}

bool BitField::in_range(std::uint64_t value) const {
  // Field values fit in 63 bits (the loader refuses ranges on wider fields), so the comparison is exact.
  const auto v = static_cast<std::int64_t>(value);
  return (!min || v >= *min) && (!max || v <= *max);
}

std::optional<unsigned> BitSet::bit(std::string_view field_name) const {
  const BitField* f = field(field_name);
  if (f == nullptr || f->width != 1) return std::nullopt;
  return f->bit;
}

const BitField* BitSet::field(std::string_view field_name) const {
  for (const auto& b : bits) {
    if (b.name == field_name) return &b;
  }
  return nullptr;
}

unsigned PdoDef::number() const {
  unsigned n = 0;
  for (std::size_t i = 4; i < name.size(); ++i) n = n * 10 + static_cast<unsigned>(name[i] - '0');
  return n;
}

std::uint16_t PdoDef::communication_index() const {
  return static_cast<std::uint16_t>((direction == PdoDirection::tx ? 0x1800 : 0x1400) + number() - 1);
}

std::uint16_t PdoDef::mapping_index() const {
  return static_cast<std::uint16_t>((direction == PdoDirection::tx ? 0x1A00 : 0x1600) + number() - 1);
}

unsigned PdoDef::mapped_bits() const {
  unsigned total = 0;
  for (const auto& e : mapping) total += e.bits;
  return total;
}

std::optional<std::uint64_t> PdoDef::manufacturer_value(std::span<const std::uint8_t> payload) const {
  if (!manufacturer_data) return std::nullopt;
  const unsigned first = mapped_bits();
  const unsigned bits = manufacturer_data->bits;
  if (bits == 0 || bits > 64 || payload.size() * 8 < first + bits) return std::nullopt;
  std::uint64_t value = 0;
  for (unsigned i = 0; i < bits; ++i) {  // CiA 301 packing: LSB first, bit by bit
    const unsigned at = first + i;
    if (((payload[at / 8] >> (at % 8)) & 1U) != 0) value |= std::uint64_t{1} << i;
  }
  return value;
}

const ObjectDef* Profile::object(std::uint16_t index, std::uint8_t sub) const {
  for (const auto& o : objects) {
    if (o.index == index && o.sub == sub) return &o;
  }
  return nullptr;
}

const ObjectDef* Profile::object(std::string_view name) const {
  for (const auto& o : objects) {
    if (o.name == name) return &o;
  }
  return nullptr;
}

const BitSet* Profile::bitset(std::string_view name) const {
  for (const auto& b : bitsets) {
    if (b.name == name) return &b;
  }
  return nullptr;
}

const PdoDef* Profile::pdo(std::string_view name) const {
  for (const auto& p : pdos) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

}  // namespace lb::profiles
