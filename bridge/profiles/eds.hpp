#pragma once
// A CANopen device description file as CiA 306 defines it: an EDS (a device model: its objects,
// data types, access and default values) or a DCF (one configured device: a node-ID and the
// values it holds, ParameterValue). INI format; object sections [1018] and [1018sub2]; values in
// decimal, 0x hex or leading-0 octal, possibly "$NODEID+0x180".

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "base/result.hpp"
#include "canopen/data_type.hpp"

namespace lb::profiles {

struct EdsEntry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::string name;                       // ParameterName
  std::optional<canopen::DataType> type;  // nullopt: a type linebridge has no use for (DOMAIN, ...)
  std::uint16_t type_code = 0;            // DataType as written (0x0007 = UNSIGNED32)
  std::string access;                     // ro, wo, rw, rwr, rww, const (lower case)
  std::string default_value;              // DefaultValue as written
  std::string parameter_value;            // ParameterValue (DCF) as written
  bool pdo_mapping = false;
  std::string where;  // "file:line" of its section
};

struct EdsFile {
  std::string source;
  std::string vendor_name, product_name;
  std::optional<std::uint32_t> vendor_number, product_number, revision_number;
  std::optional<std::uint8_t> node_id;  // a DCF's [DeviceComissioning] NodeID
  std::vector<EdsEntry> entries;        // every VAR: plain objects as sub 0, sub-indices of records/arrays

  const EdsEntry* find(std::uint16_t index, std::uint8_t sub) const;
  // The value a device starts with (a DCF's ParameterValue, else DefaultValue), $NODEID resolved;
  // nullopt for an absent entry or an empty value; an error for text that is not a number.
  Result<std::optional<std::uint64_t>> value(std::uint16_t index, std::uint8_t sub,
                                             std::optional<std::uint8_t> node_id) const;
};

// "0x1A4", "420", "0644" (octal), "$NODEID+0x180", "0x180+$NODEID" (node_id needed then).
Result<std::uint64_t> eds_number(std::string_view text, std::optional<std::uint8_t> node_id);

Result<EdsFile> parse_eds(const std::string& text, const std::string& source);
Result<EdsFile> load_eds(const std::string& path);

}  // namespace lb::profiles
