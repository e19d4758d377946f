#include "sim/pdo_parameters.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "canopen/sdo_abort.hpp"

namespace lb::sim {

using profiles::PdoAccess;
using profiles::PdoDirection;
namespace abort = canopen::sdo_abort;

namespace {

// CiA 301 7.3.5: 11-bit identifiers no PDO may use (NMT, SYNC/EMCY range, TIME, SDO, NMT error
// control, reserved).
bool restricted(std::uint32_t id) {
  return id <= 0x07F || (id >= 0x101 && id <= 0x180) || (id >= 0x581 && id <= 0x5FF) || (id >= 0x601 && id <= 0x67F) ||
         (id >= 0x6E0 && id <= 0x6FF) || id >= 0x701;
}

// CiA 301 dummy entries 0001h..0007h: BOOLEAN, INTEGER8/16/32, UNSIGNED8/16/32.
unsigned dummy_bits(std::uint16_t index) {
  static constexpr unsigned kBits[] = {0, 1, 8, 16, 32, 8, 16, 32};
  return index <= 7 ? kBits[index] : 0;
}

unsigned mapped_bits(const PdoParameters& pdo, std::uint8_t count) {
  unsigned bits = 0;
  for (std::size_t i = 0; i < count && i < pdo.entries.size(); ++i) bits += pdo.entries[i] & 0xFF;
  return bits;
}

}  // namespace

std::vector<canopen::PdoEntry> PdoParameters::mapped() const {
  std::vector<canopen::PdoEntry> out;
  for (std::size_t i = 0; i < count && i < entries.size(); ++i) out.push_back(canopen::PdoEntry::from_u32(entries[i]));
  return out;
}

PdoParameters power_on_parameters(const profiles::PdoDef& def, const profiles::DeviceConfig& device) {
  const bool tx = def.direction == PdoDirection::tx;
  PdoParameters p;
  // "either" (feeder TPDO1): this device has it valid, as a pre-measuring feeder does.
  p.cob_id = (def.validity == profiles::PdoValidity::not_valid ? cob_bits::invalid : 0) | cob_bits::no_rtr |
             def.cob_id(device.node_id);
  p.transmission_type = def.transmission_type;
  for (const auto& e : def.mapping) p.entries.push_back(e.to_u32());
  p.count = static_cast<std::uint8_t>(def.mapping.size());
  const std::uint32_t manufacturer = std::uint32_t{tx ? kSecondStatusWord : kSecondControlWord} << 16 | 0x10;
  for (unsigned i = 0; i < def.rules.manufacturer_entries; ++i) p.entries.push_back(manufacturer);

  const auto own = std::find_if(device.simulation.pdos.begin(), device.simulation.pdos.end(),
                                [&](const profiles::SimulatedPdo& s) { return s.name == def.name; });
  if (own == device.simulation.pdos.end()) return p;
  const auto fail = [&](const std::string& what) {
    throw std::runtime_error(fmt::format("{}: simulation pdos {}: {}", device.name, def.name, what));
  };
  if (own->cob_id) {
    const std::uint32_t v = *own->cob_id;
    if ((v & cob_bits::extended) == 0 && (v & cob_bits::identifier) > 0x7FF)
      fail(fmt::format("COB-ID {:08X}h: an 11-bit identifier above 7FFh", v));
    p.cob_id = v;
  }
  if (own->transmission_type) {
    if (check_transmission_type(def.direction, *own->transmission_type)) {
      fail(fmt::format("transmission type {} is reserved for a {}", *own->transmission_type, tx ? "TPDO" : "RPDO"));
    }
    p.transmission_type = *own->transmission_type;
  }
  if (own->inhibit_time_100us) p.inhibit_time = *own->inhibit_time_100us;
  if (own->event_timer_ms) p.event_timer = *own->event_timer_ms;
  if (own->mapping) {
    // The device's own mapping replaces the first entries; further ones keep their defaults.
    const auto& m = *own->mapping;
    if (m.size() > p.entries.size()) p.entries.resize(m.size());
    for (std::size_t i = 0; i < m.size(); ++i) p.entries[i] = m[i].to_u32();
    p.count = static_cast<std::uint8_t>(m.size());
  }
  return p;
}

std::uint8_t highest_communication_sub(const profiles::PdoRules& rules) {
  if (rules.event_timer != PdoAccess::none) return 5;
  if (rules.inhibit_time != PdoAccess::none) return 3;
  return 2;
}

std::optional<std::uint32_t> check_cob_id(PdoDirection direction, PdoAccess access, std::uint32_t current,
                                          std::uint32_t wanted) {
  // Bit 30 of an RPDO is reserved: whatever a master writes there changes nothing.
  const std::uint32_t ignored = direction == PdoDirection::rx ? cob_bits::no_rtr : 0;
  const std::uint32_t changed = (current ^ wanted) & ~ignored;
  if (access == PdoAccess::valid_bit) {
    if ((changed & ~cob_bits::invalid) != 0) return abort::value_range_exceeded;
    return std::nullopt;
  }
  const bool extended = (wanted & cob_bits::extended) != 0;
  const std::uint32_t id = wanted & cob_bits::identifier;
  if (!extended && id > 0x7FF) return abort::value_range_exceeded;
  const bool was_valid = (current & cob_bits::invalid) == 0;
  const bool valid = (wanted & cob_bits::invalid) == 0;
  // CiA 301: a valid PDO keeps its identifier; a master invalidates it first.
  if (was_valid && valid && (changed & (cob_bits::extended | cob_bits::identifier)) != 0)
    return abort::value_range_exceeded;
  // Restricted identifiers matter once the PDO is used; a master may park an invalid PDO anywhere.
  if (valid && !extended && restricted(id)) return abort::value_range_exceeded;
  return std::nullopt;
}

std::optional<std::uint32_t> check_transmission_type(PdoDirection direction, std::uint8_t type) {
  if (type <= 240 || type >= 254) return std::nullopt;
  // 241..251 are reserved; 252/253 (on remote request) exist only for TPDOs.
  if (direction == PdoDirection::tx && type >= 252) return std::nullopt;
  return abort::value_range_exceeded;
}

std::optional<std::uint32_t> check_state(PdoAccess access, bool operational) {
  if (operational && access == PdoAccess::rw_preop) return abort::cannot_store_device_state;
  return std::nullopt;
}

bool can_invalidate(const profiles::PdoRules& rules) {
  return rules.cob_id == PdoAccess::rw || rules.cob_id == PdoAccess::rw_preop || rules.cob_id == PdoAccess::valid_bit;
}

std::optional<std::uint32_t> check_inhibit_time(const PdoParameters& pdo, std::uint16_t wanted) {
  // CiA 301: "shall not be changed while the PDO exists"; Lely: CO_SDO_AC_PARAM_VAL.
  if (pdo.valid() && wanted != pdo.inhibit_time) return abort::value_range_exceeded;
  return std::nullopt;
}

std::optional<std::uint32_t> check_mapping_while_valid(const PdoParameters& pdo, const profiles::PdoRules& rules,
                                                       bool operational) {
  if (!pdo.valid()) return std::nullopt;
  // CiA 301's sequence: COB-ID bit 31 set first. Lely: CO_SDO_AC_PARAM_VAL.
  if (can_invalidate(rules)) return abort::value_range_exceeded;
  // A PDO that can never be made invalid: the profile's rw mapping is taken while not operational.
  if (operational) return abort::cannot_store_device_state;
  return std::nullopt;
}

std::optional<std::uint32_t> check_mapping_count(const PdoParameters& pdo, const profiles::PdoRules& rules,
                                                 std::uint8_t count) {
  if (count > pdo.entries.size()) return abort::value_range_exceeded;
  if (!rules.mapping_counts.empty() &&
      std::find(rules.mapping_counts.begin(), rules.mapping_counts.end(), count) == rules.mapping_counts.end()) {
    return abort::value_range_exceeded;
  }
  if (mapped_bits(pdo, count) > 64) return abort::pdo_length_exceeded;
  return std::nullopt;
}

std::optional<std::uint32_t> check_mapping_entry(PdoDirection direction, std::uint32_t entry,
                                                 const canopen::ObjectDictionary& dictionary,
                                                 const canopen::ProcessImage& image) {
  const auto e = canopen::PdoEntry::from_u32(entry);
  if (e.is_dummy()) {
    // A dummy only skips bits of a received PDO.
    if (direction == PdoDirection::tx || e.bits != dummy_bits(e.index)) return abort::cannot_be_mapped;
    return std::nullopt;
  }
  const auto* object = dictionary.find(e.index, e.sub);
  if (object == nullptr) return abort::no_such_object;
  // Only the device's process values can travel in a PDO (not its communication objects, strings
  // or commands such as the simulation control).
  if (image.find(e.index, e.sub) == canopen::ProcessImage::npos) return abort::cannot_be_mapped;
  if (canopen::bit_size(object->type) == 0 || canopen::bit_size(object->type) != e.bits) return abort::cannot_be_mapped;
  const bool readable = object->access != canopen::ObjectAccess::wo;
  const bool writable = object->access == canopen::ObjectAccess::rw || object->access == canopen::ObjectAccess::wo;
  if (direction == PdoDirection::tx ? !readable : !writable) return abort::cannot_be_mapped;
  return std::nullopt;
}

}  // namespace lb::sim
