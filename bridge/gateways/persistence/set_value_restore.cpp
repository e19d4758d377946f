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

RestoreScope restore_scope(const profiles::StartupPolicy& policy, bool found_operational, bool starts_itself,
                           bool paused_by_boot) {
  if (found_operational && !starts_itself && !paused_by_boot) return RestoreScope::all;
  if (paused_by_boot && !starts_itself) return RestoreScope::non_enabling;
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

namespace {

// Calls visit(name, value&) for every enabling level of the unpacked values, then packs them back
// over the mapped bytes only (bytes after them, a manufacturer-specific tail, stay) when any changed.
template <class Visit>
void each_enabling(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                   std::span<std::uint8_t> payload, Visit visit) {
  canopen::PdoMapping::Values raw{};
  if (!mapping.unpack(payload, raw)) return;  // a payload shorter than the mapping is left as it is
  const auto before = raw;
  const auto entries = mapping.entries();
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const auto& e = entries[i];
    if (e.is_dummy()) continue;
    if (const auto* obj = profile.object(e.index, e.sub); obj != nullptr && obj->enabling) {
      const std::uint64_t ones = e.bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << e.bits) - 1;
      visit(obj->name, raw[i], ones);
    }
    for (const auto& set : profile.bitsets) {
      if (!set.applies_to(e.index, e.sub)) continue;
      for (const auto& f : set.bits) {
        if (!f.enabling) continue;
        std::uint64_t v = f.extract(raw[i]);
        const std::uint64_t ones = f.width >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << f.width) - 1;
        visit(f.name, v, ones);
        raw[i] = f.insert(raw[i], v);
      }
    }
  }
  if (raw == before) return;
  std::array<std::uint8_t, 8> packed{};
  const auto n = mapping.pack(std::span<const std::uint64_t>(raw.data(), entries.size()), packed);
  std::copy_n(packed.begin(), std::min<std::size_t>(n, payload.size()), payload.begin());
}

}  // namespace

std::vector<std::string> clear_enabling(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                                        std::span<std::uint8_t> payload) {
  std::vector<std::string> cleared;
  each_enabling(profile, mapping, payload, [&cleared](const std::string& name, std::uint64_t& v, std::uint64_t) {
    if (v == 0) return;
    cleared.push_back(name);
    v = 0;
  });
  return cleared;
}

std::vector<EnablingLevel> enabling_levels(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                                           std::span<const std::uint8_t> payload) {
  std::vector<EnablingLevel> levels;
  std::array<std::uint8_t, 8> copy{};
  const auto n = std::min<std::size_t>(payload.size(), copy.size());
  std::copy_n(payload.begin(), n, copy.begin());
  each_enabling(profile, mapping, std::span<std::uint8_t>(copy.data(), n),
                [&levels](const std::string& name, std::uint64_t& v, std::uint64_t) {
                  levels.push_back({name, v});
                });
  return levels;
}

void force_enabling(const profiles::Profile& profile, const canopen::PdoMapping& mapping,
                    std::span<std::uint8_t> payload, bool on) {
  each_enabling(profile, mapping, payload,
                [on](const std::string&, std::uint64_t& v, std::uint64_t ones) { v = on ? ones : 0; });
}

}  // namespace lb::gateways
