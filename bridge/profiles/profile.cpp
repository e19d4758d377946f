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
  const double value = canopen::is_signed_integer(type)
                           ? static_cast<double>(canopen::sign_extend(raw, bits))
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
    return make_error(fmt::format("{} {}{} is out of range {}..{}{}", name, engineering, u, lo * scale,
                                  hi * scale, u));
  }
  if (raw >= 9.2e18) return static_cast<std::uint64_t>(raw);  // UNSIGNED64 beyond int64: range checked above
  return check_raw(static_cast<std::int64_t>(raw));
}

std::optional<unsigned> BitSet::bit(std::string_view field) const {
  for (const auto& b : bits) {
    if (b.name == field) return b.bit;
  }
  return std::nullopt;
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
