#include "gateways/persistence/set_value_restore.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "canopen/data_type.hpp"

namespace lb::gateways {

namespace {

std::int64_t as_signed(std::uint64_t v, unsigned bits) {
  if (bits == 0 || bits >= 64) return static_cast<std::int64_t>(v);
  const std::uint64_t sign = std::uint64_t{1} << (bits - 1);
  return static_cast<std::int64_t>((v ^ sign) - sign);
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

Result<void> check_set_values(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                              std::span<const std::uint8_t> payload) {
  canopen::PdoMapping::Values raw{};
  if (auto r = mapping.unpack(payload, raw); !r) return r;
  const auto entries = mapping.entries();
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const auto& e = entries[i];
    const auto* obj = e.is_dummy() ? nullptr : profile.object(e.index, e.sub);
    if (obj == nullptr) continue;  // a dummy entry, or an object the profile does not know
    if (canopen::is_signed_integer(obj->type) || canopen::is_unsigned_integer(obj->type)) {
      const auto value = canopen::is_signed_integer(obj->type) ? as_signed(raw[i], e.bits)
                                                               : static_cast<std::int64_t>(raw[i]);
      if (auto r = obj->check_raw(value); !r) return r.error();
    }
    if (!obj->values.valid(raw[i]))
      return make_error(fmt::format("{}: code {} is not one the profile defines", obj->name, raw[i]));
    for (const auto& set : profile.bitsets) {
      if (!set.applies_to(e.index, e.sub)) continue;
      for (const auto& f : set.bits) {
        if (!f.in_range(f.extract(raw[i]))) {
          return make_error(fmt::format("{}.{} value {} is out of its range", set.name, f.name, f.extract(raw[i])));
        }
      }
    }
  }
  return {};
}

std::vector<std::string> clear_enabling(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                                        std::span<std::uint8_t> payload) {
  std::vector<std::string> cleared;
  canopen::PdoMapping::Values raw{};
  if (!mapping.unpack(payload, raw)) return cleared;
  const auto entries = mapping.entries();
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const auto& e = entries[i];
    if (e.is_dummy()) continue;
    if (const auto* obj = profile.object(e.index, e.sub); obj != nullptr && obj->enabling && raw[i] != 0) {
      cleared.push_back(obj->name);
      raw[i] = 0;
    }
    for (const auto& set : profile.bitsets) {
      if (!set.applies_to(e.index, e.sub)) continue;
      for (const auto& f : set.bits) {
        if (!f.enabling || f.extract(raw[i]) == 0) continue;
        cleared.push_back(f.name);
        raw[i] = f.insert(raw[i], 0);
      }
    }
  }
  if (cleared.empty()) return cleared;
  // Packed back over the mapped bytes only: bytes after them (a manufacturer-specific tail) stay.
  std::array<std::uint8_t, 8> packed{};
  const auto n = mapping.pack(std::span<const std::uint64_t>(raw.data(), entries.size()), packed);
  std::copy_n(packed.begin(), std::min<std::size_t>(n, payload.size()), payload.begin());
  return cleared;
}

}  // namespace lb::gateways
