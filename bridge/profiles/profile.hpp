#pragma once
// A device profile as data: objects with type, access, unit, scaling and range; named bit fields
// of control/status/configuration words; named codes (enumerations); default PDOs. Loaded from
// config/profiles/*.yaml (format: config/profiles/README.md).

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "base/result.hpp"
#include "canopen/data_type.hpp"
#include "canopen/pdo_mapping.hpp"
#include "canopen/pdo_rules.hpp"

namespace lb::profiles {

enum class Access { ro, wo, rw, const_ };
std::string_view to_string(Access access);

// Consecutive raw codes that share one name (first == last for a single code).
struct ValueRange {
  std::uint64_t first = 0;
  std::uint64_t last = 0;
  std::string name;
};

// Named codes of an object or bit field. Codes are raw bit patterns as unpacked (zero-extended).
struct ValueTable {
  std::vector<ValueRange> ranges;  // sorted by code, never overlapping
  // true: an enumeration (600Ah loom status, ...): a code the table does not list is reserved or
  // undefined, and users must treat it as invalid rather than guess a meaning.
  // false: the value is a number and the listed codes are special values (FFFF FFFFh = scaling
  // factor not configured); every other code is just a number.
  bool exhaustive = true;

  bool empty() const { return ranges.empty(); }
  std::optional<std::string_view> name(std::uint64_t code) const;
  // The code of a name that stands for exactly one code (a command to send); nullopt for names of
  // ranges, which do not say which code to send.
  std::optional<std::uint64_t> code(std::string_view name) const;
  // False only for a code an enumeration does not define.
  bool valid(std::uint64_t code) const { return empty() || !exhaustive || name(code).has_value(); }
};

struct ObjectDef {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::string name;
  canopen::DataType type = canopen::DataType::unsigned8;
  Access access = Access::ro;
  std::string unit;                 // raw unit as the specification states it, e.g. "0.1 mm"
  double scale = 1.0;               // engineering value = raw * scale
  std::string eng_unit;             // unit of the engineering value, e.g. "m"
  std::optional<std::int64_t> min;  // raw limits for values the bridge sends
  std::optional<std::int64_t> max;
  bool mandatory = true;
  ValueTable values;  // empty: the object has no named codes
  // Any value but 0 lets the machine run (a loom status other than stop, digital outputs): after a
  // power loss or a reset it is sent as 0 until an operator sets it again (restart_after_power_loss).
  bool enabling = false;

  bool writable() const { return access == Access::rw || access == Access::wo; }
  bool readable() const { return access != Access::wo; }
  // Raw value (as unpacked from a PDO, low bits significant) to engineering units.
  double to_engineering(std::uint64_t raw) const;
  // Engineering value to raw, rounded half away from zero, refused with the reason when out of the
  // object's range (explicit min/max, else the data type's range) or not a number.
  Result<std::uint64_t> to_raw(double engineering) const;
  // The same check for a value already in raw units.
  Result<std::uint64_t> check_raw(std::int64_t raw) const;
};

// One field of a bit set: a flag (width 1) or a multi-bit field such as 6010h's winding number.
struct BitField {
  std::string name;
  unsigned bit = 0;    // lowest bit of the field
  unsigned width = 1;  // in bits
  std::string unit;    // raw unit of the field value, e.g. "0.1 ms"; empty for flags and codes
  double scale = 1.0;  // engineering value = field value * scale
  std::string eng_unit;
  std::optional<std::int64_t> min;  // printed range of the field value
  std::optional<std::int64_t> max;
  ValueTable values;
  // A level that lets the machine run (saw program on, extruder running): cleared after a power
  // loss or a reset until an operator sets it again (restart_after_power_loss).
  bool enabling = false;
  // A command that stops the machine or a function unit (stop immediately, f1 stop): never
  // refused while the device is heard, whatever the bridge knows of its boot.
  bool stopping = false;

  std::uint64_t mask() const;  // the field's bits in place within the word
  std::uint64_t extract(std::uint64_t word) const { return (word & mask()) >> bit; }
  // `word` with the field replaced by the low `width` bits of `value`.
  std::uint64_t insert(std::uint64_t word, std::uint64_t value) const;
  double to_engineering(std::uint64_t value) const { return static_cast<double>(value) * scale; }
  bool in_range(std::uint64_t value) const;
};

struct BitSet {
  std::string name;  // e.g. "status_word"
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  // The layout of every element (subs 1..n) of an ARRAY object, e.g. 6001h sub n = feeder n.
  bool every_element = false;
  std::vector<BitField> bits;

  // Position of a one-bit field; nullopt for unknown names and for multi-bit fields, so that a
  // caller reading flags never mistakes a field for a flag.
  std::optional<unsigned> bit(std::string_view field) const;
  const BitField* field(std::string_view field_name) const;
  bool applies_to(std::uint16_t object_index, std::uint8_t object_sub) const {
    return index == object_index && (every_element ? object_sub >= 1 : object_sub == sub);
  }
};

enum class PdoDirection { tx, rx };  // seen from the device: tx = TPDO (device -> master)

// COB-ID bit 31 as the device starts: the PDO exists, but may be switched off by default.
enum class PdoValidity { valid, not_valid, either };
std::string_view to_string(PdoValidity validity);

// Data a device may append after the mapped objects ("the unused bytes shall only be used for a
// manufacturer-specific second status word"): present only in frames long enough to carry it.
struct PdoTail {
  std::string name;
  unsigned bits = 0;
};

// PDO parameter access is a CANopen notion (canopen/pdo_rules.hpp); a profile states it per PDO.
using canopen::PdoAccess;
using canopen::PdoRules;

struct PdoDef {
  std::string name;  // tpdo1, rpdo1, ...: the number says which 1400h../1800h.. objects it is
  PdoDirection direction = PdoDirection::tx;
  std::uint32_t cob_id_base = 0;  // predefined connection set base; the node-ID is added
  std::uint8_t transmission_type = 1;
  std::vector<canopen::PdoEntry> mapping;
  PdoValidity validity = PdoValidity::valid;
  bool mandatory = true;  // the profile's category of the PDO
  std::optional<PdoTail> manufacturer_data;
  PdoRules rules;

  std::uint32_t cob_id(std::uint8_t node_id) const { return cob_id_base + node_id; }
  // 1..512 from the name (tpdo3 -> 3); communication parameter 1400h/1800h + number - 1, mapping
  // parameter 1600h/1A00h + number - 1.
  unsigned number() const;
  std::uint16_t communication_index() const;
  std::uint16_t mapping_index() const;
  unsigned mapped_bits() const;
  // The manufacturer-specific tail of a received frame (little-endian, after the mapped objects);
  // nullopt when the profile defines none or the frame is too short to carry it.
  std::optional<std::uint64_t> manufacturer_value(std::span<const std::uint8_t> payload) const;
};

struct Profile {
  std::string id;       // e.g. "cia420-4"
  std::string version;  // e.g. "3.1"
  std::string device;   // e.g. "saw": which gateway serves it
  std::string title;
  std::uint32_t device_type = 0;
  std::vector<ObjectDef> objects;
  std::vector<BitSet> bitsets;
  std::vector<PdoDef> pdos;

  const ObjectDef* object(std::uint16_t index, std::uint8_t sub = 0) const;
  const ObjectDef* object(std::string_view name) const;
  const BitSet* bitset(std::string_view name) const;
  const PdoDef* pdo(std::string_view name) const;
  std::string key() const { return id + "@" + version; }
};

}  // namespace lb::profiles
