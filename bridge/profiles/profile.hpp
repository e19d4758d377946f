#pragma once
// A device profile as data: objects with type, access, unit, scaling and range; named bit fields
// of control/status/configuration words; default PDOs. Loaded from config/profiles/*.yaml.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "base/result.hpp"
#include "canopen/data_type.hpp"
#include "canopen/pdo_mapping.hpp"

namespace lb::profiles {

enum class Access { ro, wo, rw, const_ };
std::string_view to_string(Access access);

struct ObjectDef {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::string name;
  canopen::DataType type = canopen::DataType::unsigned8;
  Access access = Access::ro;
  std::string unit;      // raw unit as the specification states it, e.g. "0.1 mm"
  double scale = 1.0;    // engineering value = raw * scale
  std::string eng_unit;  // unit of the engineering value, e.g. "m"
  std::optional<std::int64_t> min;  // raw limits for values the bridge sends
  std::optional<std::int64_t> max;
  bool mandatory = true;

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

struct BitField {
  std::string name;
  unsigned bit = 0;
};

struct BitSet {
  std::string name;  // e.g. "status_word"
  std::uint16_t index = 0;
  std::vector<BitField> bits;

  std::optional<unsigned> bit(std::string_view field) const;
};

enum class PdoDirection { tx, rx };  // seen from the device: tx = TPDO (device -> master)

struct PdoDef {
  std::string name;  // tpdo1, rpdo1, ...
  PdoDirection direction = PdoDirection::tx;
  std::uint32_t cob_id_base = 0;  // predefined connection set base; the node-ID is added
  std::uint8_t transmission_type = 1;
  std::vector<canopen::PdoEntry> mapping;

  std::uint32_t cob_id(std::uint8_t node_id) const { return cob_id_base + node_id; }
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
