#include "sim/device_pdos.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "canopen/sdo_abort.hpp"
#include "sim/little_endian.hpp"

namespace lb::sim {

using canopen::DataType;
using profiles::PdoAccess;

namespace {}  // namespace

DevicePdos::DevicePdos(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile,
                       canopen::ProcessImage& image, canopen::ObjectDictionary& dictionary, Hooks hooks,
                       const std::vector<std::string>& application_events)
    : loop_(loop), device_(device), image_(image), dictionary_(dictionary), hooks_(std::move(hooks)) {
  pdos_.reserve(profile.pdos.size());
  for (const auto& def : profile.pdos) {
    Pdo p;
    p.def = &def;
    p.application_events = std::find(application_events.begin(), application_events.end(), def.name) !=
                           application_events.end();
    p.power_on = power_on_parameters(def, device_);
    p.now = p.power_on;
    pdos_.push_back(std::move(p));
  }
  for (std::size_t i = 0; i < pdos_.size(); ++i) {
    add_objects(i);
    Pdo& p = pdos_[i];
    if (!tx(p)) {
      listen(i);
      continue;
    }
    p.transmitter = std::make_unique<canopen::PdoTransmitter>(
        loop_, settings(p.now),
        canopen::PdoTransmitter::Hooks{
            .pack =
                [this, i](can::CanFrame& f) {
                  const Pdo& q = pdos_[i];
                  f.len = q.binding ? q.binding->pack_from(image_, std::span<std::uint8_t, 8>(f.data)) : 0;
                },
            // Not valid, or nothing mapped (sub 0 = 0): the PDO does not exist on the bus.
            .may_send = [this, i] { return hooks_.operational() && pdos_[i].now.valid() && pdos_[i].now.count > 0; }});
  }
}

canopen::PdoTransmitter::Settings DevicePdos::settings(const PdoParameters& p) {
  return {p.can_id(), p.extended(), p.transmission_type, std::chrono::microseconds(100 * std::int64_t{p.inhibit_time}),
          std::chrono::milliseconds(p.event_timer)};
}

void DevicePdos::add(std::uint16_t index, std::uint8_t sub, DataType type, PdoAccess access, Read read, Write write) {
  const bool fixed = access == PdoAccess::fixed;
  if (auto r = dictionary_.add(index, sub, type, fixed ? canopen::ObjectAccess::const_ : canopen::ObjectAccess::rw);
      !r) {
    throw std::runtime_error(device_.name + ": " + r.error().message);
  }
  const std::size_t size = canopen::bit_size(type) / 8;
  (void)dictionary_.set_on_read(index, sub, [read = std::move(read), size] {
    const std::uint32_t v = read();
    canopen::ObjectDictionary::Bytes bytes(size);
    for (std::size_t b = 0; b < size; ++b) bytes[b] = static_cast<std::uint8_t>(v >> (8 * b));
    return bytes;
  });
  // A const or ro entry is refused by its access (06010002h) before any hook runs.
  if (fixed || !write) return;
  (void)dictionary_.set_on_write(index, sub, [write = std::move(write)](std::span<const std::uint8_t> v) {
    return write(static_cast<std::uint32_t>(little_endian(v)));
  });
}

void DevicePdos::add_objects(std::size_t i) {
  const Pdo& p = pdos_[i];
  const auto& rules = p.def->rules;
  const std::uint16_t comm = p.def->communication_index();
  const std::uint16_t map = p.def->mapping_index();
  const std::uint8_t highest = highest_communication_sub(rules);
  add(comm, 0, DataType::unsigned8, PdoAccess::fixed, [highest] { return highest; }, {});
  add(
      comm, 1, DataType::unsigned32, rules.cob_id, [this, i] { return pdos_[i].now.cob_id; },
      [this, i](std::uint32_t v) { return write_cob_id(i, v); });
  add(
      comm, 2, DataType::unsigned8, rules.transmission_type, [this, i] { return pdos_[i].now.transmission_type; },
      [this, i](std::uint32_t v) {
        const auto type = static_cast<std::uint8_t>(v);
        return write_communication(i, pdos_[i].def->rules.transmission_type,
                                   check_transmission_type(pdos_[i].def->direction, type),
                                   [type](Pdo& q) { q.now.transmission_type = type; });
      });
  if (rules.inhibit_time != PdoAccess::none) {
    add(
        comm, 3, DataType::unsigned16, rules.inhibit_time, [this, i] { return pdos_[i].now.inhibit_time; },
        [this, i](std::uint32_t v) {
          const auto inhibit = static_cast<std::uint16_t>(v);
          return write_communication(i, pdos_[i].def->rules.inhibit_time, check_inhibit_time(pdos_[i].now, inhibit),
                                     [inhibit](Pdo& q) { q.now.inhibit_time = inhibit; });
        });
  }
  if (rules.event_timer != PdoAccess::none) {
    add(
        comm, 5, DataType::unsigned16, rules.event_timer, [this, i] { return pdos_[i].now.event_timer; },
        [this, i](std::uint32_t v) {
          return write_communication(i, pdos_[i].def->rules.event_timer, std::nullopt,
                                     [v](Pdo& q) { q.now.event_timer = static_cast<std::uint16_t>(v); });
        });
  }
  add(
      map, 0, DataType::unsigned8, rules.mapping_count, [this, i] { return pdos_[i].now.count; },
      [this, i](std::uint32_t v) { return write_count(i, v); });
  for (std::size_t e = 0; e < p.now.entries.size(); ++e) {
    add(
        map, static_cast<std::uint8_t>(e + 1), DataType::unsigned32, rules.mapping,
        [this, i, e] { return pdos_[i].now.entries[e]; },
        [this, i, e](std::uint32_t v) { return write_entry(i, e, v); });
  }
}

std::optional<std::uint32_t> DevicePdos::write_cob_id(std::size_t i, std::uint32_t v) {
  Pdo& p = pdos_[i];
  if (auto code = check_state(p.def->rules.cob_id, hooks_.operational())) return code;
  if (auto code = check_cob_id(p.def->direction, p.def->rules.cob_id, p.now.cob_id, v)) return code;
  p.now.cob_id = v;
  communication_changed(p, i);
  return std::nullopt;
}

std::optional<std::uint32_t> DevicePdos::write_communication(std::size_t i, PdoAccess access,
                                                             std::optional<std::uint32_t> out_of_range,
                                                             const std::function<void(Pdo&)>& set) {
  Pdo& p = pdos_[i];
  if (auto code = check_state(access, hooks_.operational())) return code;
  if (out_of_range) return out_of_range;
  set(p);
  communication_changed(p, i);
  return std::nullopt;
}

std::optional<std::uint32_t> DevicePdos::write_count(std::size_t i, std::uint32_t v) {
  Pdo& p = pdos_[i];
  const auto count = static_cast<std::uint8_t>(v);
  if (auto code = check_state(p.def->rules.mapping_count, hooks_.operational())) return code;
  if (count == p.now.count) return std::nullopt;  // as Lely: the value it has is no change
  if (auto code = check_mapping_while_valid(p.now, p.def->rules, hooks_.operational())) return code;
  if (auto code = check_mapping_count(p.now, p.def->rules, count)) return code;
  p.now.count = count;
  rebind(p);
  return std::nullopt;
}

std::optional<std::uint32_t> DevicePdos::write_entry(std::size_t i, std::size_t entry, std::uint32_t v) {
  Pdo& p = pdos_[i];
  if (auto code = check_state(p.def->rules.mapping, hooks_.operational())) return code;
  if (v == p.now.entries[entry]) return std::nullopt;  // as Lely: the value it has is no change
  if (auto code = check_mapping_while_valid(p.now, p.def->rules, hooks_.operational())) return code;
  // CiA 301: entries change only while sub 0 is 0 (the mapping switched off); Lely answers
  // CO_SDO_AC_PARAM_VAL (0609 0030h).
  if (p.now.count != 0) return canopen::sdo_abort::value_range_exceeded;
  if (auto code = check_mapping_entry(p.def->direction, v, dictionary_, image_)) return code;
  p.now.entries[entry] = v;
  return std::nullopt;
}

void DevicePdos::communication_changed(Pdo& p, std::size_t i) {
  if (!tx(p)) {
    listen(i);
    if (!p.now.valid()) p.pending.reset();
    return;
  }
  p.transmitter->reconfigure(settings(p.now));
  // An event timer runs from the change on; resend() also sends the current values once.
  if (hooks_.operational() && p.now.transmission_type >= 254 && p.now.event_timer > 0) p.transmitter->resend();
}

void DevicePdos::rebind(Pdo& p) {
  p.pending.reset();  // data packed for the old mapping
  auto mapping = canopen::PdoMapping::create(p.now.mapped());
  if (!mapping) {
    p.binding.reset();  // unreachable: counts and entries were checked
    return;
  }
  p.binding.emplace(std::move(*mapping), image_);
}

void DevicePdos::listen(std::size_t i) {
  Pdo& p = pdos_[i];
  const std::pair<std::uint32_t, bool> key{p.now.can_id(), p.now.extended()};
  for (const auto& k : p.listening) {
    if (k == key) return;
  }
  p.listening.push_back(key);
  auto handler = [this, i, key](const can::CanFrame& f) {
    Pdo& q = pdos_[i];
    if (!hooks_.operational() || !q.now.valid() || q.now.can_id() != key.first || q.now.extended() != key.second)
      return;
    receive(q, f);
  };
  if (key.second)
    loop_.on_extended_frame(key.first, std::move(handler));
  else
    loop_.on_frame(key.first, std::move(handler));
}

void DevicePdos::receive(Pdo& p, const can::CanFrame& frame) {
  if (!p.binding) return;
  const std::size_t needed = p.binding->mapping().byte_length();
  if (frame.len < needed) {
    if (hooks_.too_short) hooks_.too_short(*p.def, frame.len, needed);
    return;
  }
  if (p.now.synchronous())
    p.pending = frame;  // the last one before the SYNC counts
  else
    apply(p, frame);
}

void DevicePdos::apply(Pdo& p, const can::CanFrame& frame) {
  if (!p.binding || p.binding->mapping().entries().empty()) return;
  if (!p.binding->unpack_into(frame.payload(), image_)) return;  // length checked on reception
  if (hooks_.received) hooks_.received(p.binding->mapping().entries());
}

void DevicePdos::check_power_on() const {
  for (const auto& p : pdos_) {
    const auto fail = [&](std::size_t sub, std::uint32_t entry, std::uint32_t code) {
      throw std::runtime_error(fmt::format("{}: {} mapping sub {} = {:08X}h: {:08X}h {}", device_.name, p.def->name,
                                           sub, entry, code, canopen::sdo_abort_meaning(code)));
    };
    for (std::size_t e = 0; e < p.power_on.count; ++e) {
      if (auto code = check_mapping_entry(p.def->direction, p.power_on.entries[e], dictionary_, image_)) {
        fail(e + 1, p.power_on.entries[e], *code);
      }
    }
    // The count as the device has it, whatever the profile's list of counts says.
    profiles::PdoRules any = p.def->rules;
    any.mapping_counts.clear();
    if (auto code = check_mapping_count(p.power_on, any, p.power_on.count)) fail(0, p.power_on.count, *code);
  }
}

void DevicePdos::reset() {
  if (!checked_) {
    check_power_on();
    checked_ = true;
  }
  for (auto& p : pdos_) {
    p.now = p.power_on;
    rebind(p);
    // An RPDO's power-on identifier has had its handler since construction.
    if (tx(p)) p.transmitter->reconfigure(settings(p.now));
  }
}

void DevicePdos::started() {
  for (auto& p : pdos_) {
    if (!tx(p)) continue;
    p.transmitter->reconfigure(settings(p.now));
    if (p.now.transmission_type >= 254 && p.now.event_timer > 0) p.transmitter->resend();
  }
}

void DevicePdos::left_operational() {
  for (auto& p : pdos_) p.pending.reset();
}

void DevicePdos::apply_pending() {
  for (auto& p : pdos_) {
    if (!p.pending) continue;
    const can::CanFrame frame = *p.pending;
    p.pending.reset();
    apply(p, frame);
  }
}

void DevicePdos::on_sync() {
  for (auto& p : pdos_) {
    if (!tx(p)) continue;
    p.transmitter->on_sync();
    if (!p.application_events) p.transmitter->on_data();
  }
}

void DevicePdos::data_changed() {
  for (auto& p : pdos_) {
    if (tx(p) && !p.application_events) p.transmitter->on_data();
  }
}

bool DevicePdos::event(std::string_view tpdo) {
  for (auto& p : pdos_) {
    if (tx(p) && p.def->name == tpdo) {
      p.transmitter->resend();
      return true;
    }
  }
  return false;
}

}  // namespace lb::sim
