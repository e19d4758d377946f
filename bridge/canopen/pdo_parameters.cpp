#include "canopen/pdo_parameters.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace lb::canopen {

namespace {

std::string hex(std::uint32_t v) { return fmt::format("{:04X}h", v); }

std::string values_of(const std::vector<std::uint8_t>& counts) {
  std::string s;
  for (auto c : counts) s += (s.empty() ? "" : ", ") + std::to_string(c);
  return s;
}

class Planner {
 public:
  Planner(const PdoSpec& spec, const DevicePdo& device)
      : spec_(spec),
        want_(spec.wanted),
        have_(device.parameters),
        device_(device),
        pdo_(fmt::format("{} ({}/{})", spec.name, hex(spec.communication_index), hex(spec.mapping_index))) {}

  Result<PdoPlan, PdoMismatch> run() {
    const std::uint32_t cob = target_cob_id();
    if (cob != have_.cob_id) {
      const bool only_valid_bit = ((cob ^ have_.cob_id) & ~kCobIdNotValid) == 0;
      if (!writable(spec_.rules.cob_id) && !(spec_.rules.cob_id == PdoAccess::valid_bit && only_valid_bit)) {
        return refuse(spec_.communication_index, 1, describe_cob_id(cob), describe_cob_id(have_.cob_id), "COB-ID",
                      spec_.rules.cob_id);
      }
    }
    if (want_.transmission_type != have_.transmission_type && !writable(spec_.rules.transmission_type)) {
      return refuse(spec_.communication_index, 2, std::to_string(want_.transmission_type),
                    std::to_string(have_.transmission_type), "transmission type", spec_.rules.transmission_type);
    }
    // An RPDO's inhibit time and event timer are how the master sends it: the device keeps its own.
    if (spec_.transmit) {
      if (auto m = timing(3, "inhibit time", want_.inhibit_time, have_.inhibit_time, device_.has_inhibit_time,
                          spec_.rules.inhibit_time)) {
        return *m;
      }
      if (auto m = timing(5, "event timer", want_.event_timer, have_.event_timer, device_.has_event_timer,
                          spec_.rules.event_timer)) {
        return *m;
      }
    }
    if (auto m = check_mapping()) return *m;
    return plan(cob);
  }

 private:
  // Bit 30 (no RTR) stays the device's: CiA 420 fixes it, and it is reserved for RPDOs.
  std::uint32_t target_cob_id() const {
    const bool valid = spec_.validity_given ? want_.valid() : have_.valid();
    return (want_.cob_id & ~(kCobIdNotValid | kCobIdNoRtr)) | (valid ? 0 : kCobIdNotValid) |
           (have_.cob_id & kCobIdNoRtr);
  }

  std::optional<PdoEntry> device_entry(std::size_t i) const {
    if (i < have_.mapping.size()) return have_.mapping[i];
    const std::size_t extra = i - have_.mapping.size();
    if (extra < device_.unmapped.size()) return device_.unmapped[extra];
    return std::nullopt;
  }

  std::optional<PdoMismatch> timing(std::uint8_t sub, const char* what, std::uint16_t want, std::uint16_t have,
                                    bool present, PdoAccess access) const {
    if (want == have) return std::nullopt;
    if (!present || access == PdoAccess::none) {
      return mismatch(spec_.communication_index, sub, std::to_string(want), "absent",
                      fmt::format("{}: the device has no {} ({} sub {}), the line wants {}", pdo_, what,
                                  hex(spec_.communication_index), sub, want));
    }
    if (!writable(access)) {
      return refuse(spec_.communication_index, sub, std::to_string(want), std::to_string(have), what, access);
    }
    // CiA 301: the inhibit time changes only while the PDO is not valid. A PDO whose COB-ID the
    // profile fixes (saw 3.1: const) cannot be made invalid, so its inhibit time cannot be written,
    // whatever the profile's table says of sub 3 (a device refuses it: Lely with 0609 0030h).
    if (sub == 3 && have_.valid() && !can_invalidate()) {
      return mismatch(spec_.communication_index, sub, std::to_string(want), std::to_string(have),
                      fmt::format("{}: inhibit time {} sub 3 is {} on the device, the line wants {}; CiA 301 lets a "
                                  "master change it only while the PDO is not valid, and the device profile makes the "
                                  "COB-ID ({} sub 1) {}, so the bridge cannot make it invalid",
                                  pdo_, hex(spec_.communication_index), have, want, hex(spec_.communication_index),
                                  to_string(spec_.rules.cob_id)));
    }
    return std::nullopt;
  }

  std::optional<PdoMismatch> check_mapping() {
    for (std::size_t i = 0; i < want_.mapping.size(); ++i) {
      const auto entry = device_entry(i);
      if (entry && *entry == want_.mapping[i]) continue;
      entries_change_ = true;
      if (!writable(spec_.rules.mapping)) {
        return refuse(spec_.mapping_index, static_cast<std::uint8_t>(i + 1), describe_entry(want_.mapping[i]),
                      entry ? describe_entry(*entry) : "absent", "mapping entry", spec_.rules.mapping);
      }
    }
    count_change_ = want_.mapping.size() != have_.mapping.size();
    if (!count_change_ && !entries_change_) return std::nullopt;
    const auto count = std::to_string(want_.mapping.size());
    if (!writable(spec_.rules.mapping_count)) {
      return refuse(spec_.mapping_index, 0, count, std::to_string(have_.mapping.size()), "number of mapped objects",
                    spec_.rules.mapping_count);
    }
    const auto& allowed = spec_.rules.mapping_counts;
    if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), want_.mapping.size()) == allowed.end()) {
      return mismatch(spec_.mapping_index, 0, count, std::to_string(have_.mapping.size()),
                      fmt::format("{}: {} objects cannot be mapped: the profile allows {} sub 0 = {} only", pdo_, count,
                                  hex(spec_.mapping_index), values_of(allowed)));
    }
    return std::nullopt;
  }

  PdoPlan plan(std::uint32_t cob) {
    PdoPlan p;
    const auto comm = spec_.communication_index;
    const auto map = spec_.mapping_index;
    const bool identifier_change = ((cob ^ have_.cob_id) & ~kCobIdNotValid) != 0;
    const bool mapping_change = entries_change_ || count_change_;
    const bool inhibit_change = spec_.transmit && want_.inhibit_time != have_.inhibit_time;
    // CiA 301: a PDO's identifier, inhibit time and mapping change only while it is not valid
    // (bit 31 set first, cleared last); the transmission type and event timer at any time.
    const bool invalidate = (mapping_change || identifier_change || inhibit_change) && have_.valid() &&
                            can_invalidate();
    if (invalidate) p.writes.push_back({comm, 1, 32, have_.cob_id | kCobIdNotValid});
    if (entries_change_) {
      p.writes.push_back({map, 0, 8, 0});
      for (std::size_t i = 0; i < want_.mapping.size(); ++i) {
        const auto entry = device_entry(i);
        if (!entry || *entry != want_.mapping[i]) {
          p.writes.push_back({map, static_cast<std::uint8_t>(i + 1), 32, want_.mapping[i].to_u32()});
        }
      }
    }
    if (mapping_change) p.writes.push_back({map, 0, 8, static_cast<std::uint32_t>(want_.mapping.size())});
    if (want_.transmission_type != have_.transmission_type) p.writes.push_back({comm, 2, 8, want_.transmission_type});
    if (inhibit_change) p.writes.push_back({comm, 3, 16, want_.inhibit_time});
    if (spec_.transmit && want_.event_timer != have_.event_timer) p.writes.push_back({comm, 5, 16, want_.event_timer});
    if (cob != (invalidate ? have_.cob_id | kCobIdNotValid : have_.cob_id)) p.writes.push_back({comm, 1, 32, cob});
    p.needs_not_operational = mapping_change;
    if (have_.valid() && identifier_change) {
      p.disrupts = changing(comm, 1, "COB-ID", describe_cob_id(cob), describe_cob_id(have_.cob_id));
    } else if (have_.valid() && inhibit_change) {
      p.disrupts = changing(comm, 3, "inhibit time", std::to_string(want_.inhibit_time),
                            std::to_string(have_.inhibit_time));
    } else if (mapping_change) {
      p.disrupts = changing(map, 0, "number of mapped objects", std::to_string(want_.mapping.size()),
                            std::to_string(have_.mapping.size()));
      if (entries_change_)
        p.disrupts->message = fmt::format("{}: its mapping ({}) differs from the line's", pdo_, hex(map));
    }
    p.result = have_;
    p.result.cob_id = cob;
    p.result.transmission_type = want_.transmission_type;
    if (spec_.transmit) {
      p.result.inhibit_time = want_.inhibit_time;
      p.result.event_timer = want_.event_timer;
    }
    p.result.mapping = want_.mapping;
    return p;
  }

  bool can_invalidate() const { return writable(spec_.rules.cob_id) || spec_.rules.cob_id == PdoAccess::valid_bit; }

  PdoMismatch changing(std::uint16_t index, std::uint8_t sub, const char* what, std::string expected,
                       std::string actual) const {
    auto message = fmt::format("{}: {} {} sub {} is {} on the device, the line wants {}", pdo_, what, hex(index), sub,
                               actual, expected);
    return mismatch(index, sub, std::move(expected), std::move(actual), std::move(message));
  }

  PdoMismatch mismatch(std::uint16_t index, std::uint8_t sub, std::string expected, std::string actual,
                       std::string message) const {
    return {index, sub, std::move(expected), std::move(actual), std::move(message)};
  }

  PdoMismatch refuse(std::uint16_t index, std::uint8_t sub, const std::string& expected, const std::string& actual,
                     const char* what, PdoAccess access) const {
    return mismatch(index, sub, expected, actual,
                    fmt::format("{}: {} {} sub {} is {} on the device, the line wants {}; the device profile makes it "
                                "{}, so the bridge cannot write it",
                                pdo_, what, hex(index), sub, actual, expected, to_string(access)));
  }

  const PdoSpec& spec_;
  const PdoParameters& want_;
  const PdoParameters& have_;
  const DevicePdo& device_;
  std::string pdo_;
  bool entries_change_ = false;
  bool count_change_ = false;
};

}  // namespace

std::string describe_cob_id(std::uint32_t entry) {
  const bool ext = (entry & kCobIdExtended) != 0;
  return fmt::format("{:04X} {:04X}h ({}, {} {:0{}X}h)", entry >> 16, entry & 0xFFFF,
                     (entry & kCobIdNotValid) != 0 ? "not valid" : "valid", ext ? "29-bit" : "11-bit",
                     entry & (ext ? 0x1FFF'FFFFU : 0x7FFU), ext ? 8 : 3);
}

std::string describe_entry(PdoEntry e) { return fmt::format("{:04X} {:02X} {:02X}h", e.index, e.sub, e.bits); }

Result<PdoPlan, PdoMismatch> plan_pdo(const PdoSpec& spec, const DevicePdo& device) {
  if (device.absent) {
    PdoPlan p;  // nothing to write: the PDO is not there, so it is not used
    p.result = spec.wanted;
    p.result.cob_id |= kCobIdNotValid;
    return p;
  }
  return Planner(spec, device).run();
}

PdoSpec adopt_device_pdo(const PdoSpec& spec, const DevicePdo& device) {
  PdoSpec adopted = spec;
  const auto& have = device.parameters;
  adopted.wanted.transmission_type = have.transmission_type;
  adopted.wanted.inhibit_time = have.inhibit_time;
  adopted.wanted.event_timer = have.event_timer;
  adopted.wanted.mapping = have.mapping;
  adopted.validity_given = false;
  return adopted;
}

std::optional<PdoMismatch> verify_pdo(const PdoSpec& spec, const PdoParameters& planned, const DevicePdo& read_back) {
  const auto& got = read_back.parameters;
  const auto differs = [&](std::uint16_t index, std::uint8_t sub, std::string expected, std::string actual) {
    return PdoMismatch{index, sub, expected, actual,
                       fmt::format("{}: {} sub {} was written as {} and the device confirmed it, but it reads back {} "
                                   "(the device ignored the write)",
                                   spec.name, hex(index), sub, expected, actual)};
  };
  if (((got.cob_id ^ planned.cob_id) & ~kCobIdNoRtr) != 0) {
    return differs(spec.communication_index, 1, describe_cob_id(planned.cob_id), describe_cob_id(got.cob_id));
  }
  if (got.transmission_type != planned.transmission_type) {
    return differs(spec.communication_index, 2, std::to_string(planned.transmission_type),
                   std::to_string(got.transmission_type));
  }
  if (spec.transmit && read_back.has_inhibit_time && got.inhibit_time != planned.inhibit_time) {
    return differs(spec.communication_index, 3, std::to_string(planned.inhibit_time), std::to_string(got.inhibit_time));
  }
  if (spec.transmit && read_back.has_event_timer && got.event_timer != planned.event_timer) {
    return differs(spec.communication_index, 5, std::to_string(planned.event_timer), std::to_string(got.event_timer));
  }
  if (got.mapping.size() != planned.mapping.size()) {
    return differs(spec.mapping_index, 0, std::to_string(planned.mapping.size()), std::to_string(got.mapping.size()));
  }
  for (std::size_t i = 0; i < got.mapping.size(); ++i) {
    if (got.mapping[i] != planned.mapping[i]) {
      return differs(spec.mapping_index, static_cast<std::uint8_t>(i + 1), describe_entry(planned.mapping[i]),
                     describe_entry(got.mapping[i]));
    }
  }
  return std::nullopt;
}

}  // namespace lb::canopen
