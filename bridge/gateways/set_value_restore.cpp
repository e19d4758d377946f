#include "gateways/set_value_restore.hpp"

#include <fmt/format.h>

#include "canopen/data_type.hpp"

namespace lb::gateways {

namespace {

// The little-endian bit field [offset, offset + bits) of a payload (CiA 301 packs PDOs that way).
std::uint64_t get_bits(std::span<const std::uint8_t> payload, unsigned offset, unsigned bits) {
  std::uint64_t v = 0;
  for (unsigned i = 0; i < bits; ++i) {
    const unsigned at = offset + i;
    if (at / 8 >= payload.size()) break;
    if ((payload[at / 8] >> (at % 8)) & 1U) v |= std::uint64_t{1} << i;
  }
  return v;
}

void set_bits(std::span<std::uint8_t> payload, unsigned offset, unsigned bits, std::uint64_t v) {
  for (unsigned i = 0; i < bits; ++i) {
    const unsigned at = offset + i;
    if (at / 8 >= payload.size()) break;
    const auto mask = static_cast<std::uint8_t>(1U << (at % 8));
    if ((v >> i) & 1U) payload[at / 8] |= mask;
    else payload[at / 8] &= static_cast<std::uint8_t>(~mask);
  }
}

std::int64_t as_signed(std::uint64_t v, unsigned bits) {
  if (bits == 0 || bits >= 64) return static_cast<std::int64_t>(v);
  const std::uint64_t sign = std::uint64_t{1} << (bits - 1);
  return static_cast<std::int64_t>((v ^ sign) - sign);
}

// Calls f(entry, object or null, offset) for every mapped entry that fits the payload.
template <class F>
void each_entry(const profiles::Profile& profile, std::span<const canopen::PdoEntry> mapping, std::size_t payload_bytes, F f) {
  unsigned offset = 0;
  for (const auto& e : mapping) {
    if (offset + e.bits > payload_bytes * 8) return;
    if (!e.is_dummy()) f(e, profile.object(e.index, e.sub), offset);
    offset += e.bits;
  }
}

}  // namespace

std::string_view to_string(RestoreScope scope) {
  switch (scope) {
    case RestoreScope::all: return "all";
    case RestoreScope::non_enabling: return "non-enabling";
    case RestoreScope::nothing: return "nothing";
  }
  return "?";
}

RestoreScope restore_scope(const profiles::StartupPolicy& policy, bool found_operational, bool starts_itself) {
  if (found_operational && !starts_itself) return RestoreScope::all;
  if (policy.after_power_loss == profiles::StartupPolicy::AfterPowerLoss::nothing) return RestoreScope::nothing;
  return policy.restart_after_power_loss == profiles::StartupPolicy::Restart::allowed ? RestoreScope::all
                                                                                      : RestoreScope::non_enabling;
}

Result<void> check_set_values(const profiles::Profile& profile, std::span<const canopen::PdoEntry> mapping,
                              std::span<const std::uint8_t> payload) {
  std::string problem;
  each_entry(profile, mapping, payload.size(), [&](const canopen::PdoEntry& e, const profiles::ObjectDef* obj, unsigned at) {
    if (obj == nullptr || !problem.empty()) return;
    const std::uint64_t raw = get_bits(payload, at, e.bits);
    const std::int64_t value = canopen::is_signed_integer(obj->type) ? as_signed(raw, e.bits) : static_cast<std::int64_t>(raw);
    if (canopen::is_signed_integer(obj->type) || canopen::is_unsigned_integer(obj->type)) {
      if (auto r = obj->check_raw(value); !r) return void(problem = r.error().message);
    }
    if (!obj->values.valid(raw)) return void(problem = fmt::format("{}: code {} is not one the profile defines", obj->name, raw));
    for (const auto& set : profile.bitsets) {
      if (!set.applies_to(e.index, e.sub)) continue;
      for (const auto& f : set.bits) {
        const auto v = f.extract(raw);
        if (!f.in_range(v)) return void(problem = fmt::format("{}.{} value {} is out of its range", set.name, f.name, v));
      }
    }
  });
  if (!problem.empty()) return make_error(problem);
  return {};
}

std::vector<std::string> clear_enabling(const profiles::Profile& profile, std::span<const canopen::PdoEntry> mapping,
                                        std::span<std::uint8_t> payload) {
  std::vector<std::string> cleared;
  each_entry(profile, mapping, payload.size(), [&](const canopen::PdoEntry& e, const profiles::ObjectDef* obj, unsigned at) {
    std::uint64_t raw = get_bits(payload, at, e.bits);
    if (obj != nullptr && obj->enabling) {
      if (raw != 0) cleared.push_back(obj->name);
      raw = 0;
    }
    for (const auto& set : profile.bitsets) {
      if (!set.applies_to(e.index, e.sub)) continue;
      for (const auto& f : set.bits) {
        if (!f.enabling || f.extract(raw) == 0) continue;
        cleared.push_back(f.name);
        raw = f.insert(raw, 0);
      }
    }
    set_bits(payload, at, e.bits, raw);
  });
  return cleared;
}

}  // namespace lb::gateways
