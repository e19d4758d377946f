#pragma once
// Typed object values as SDO carries them: CiA 301 data types to and from little-endian bytes.

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include "base/result.hpp"
#include "canopen/data_type.hpp"

namespace lb::canopen {

// int64: INTEGER8..64; uint64: BOOLEAN, UNSIGNED8..64; double: REAL32/64; string: VISIBLE_STRING
// (OCTET_STRING accepts it too); bytes: OCTET_STRING.
using ObjectValue = std::variant<std::int64_t, std::uint64_t, double, std::string, std::vector<std::uint8_t>>;

// Bytes a value of a fixed-size type takes in an SDO transfer (BOOLEAN: one byte); 0 for strings.
std::size_t sdo_size(DataType type);

// Little-endian bytes of value as type. Integers of either signedness are accepted when the type
// can hold them (and REAL32/64 take integers too); anything else is an error that names both sides.
Result<std::vector<std::uint8_t>> encode(DataType type, const ObjectValue& value);

// The value of bytes as type: fixed-size types need exactly sdo_size(type) bytes, strings take any
// length, and a VISIBLE_STRING ends at its first NUL (servers may pad with them).
Result<ObjectValue> decode(DataType type, std::span<const std::uint8_t> bytes);

// For logs and the CLI: 42, -7, 1.5, "text" (non-printables escaped), [01 A2 FF].
std::string to_string(const ObjectValue& value);

// An integer value's bits as read (a negative INTEGERn as its two's complement), for scaling and
// bit sets; 0 for strings, a REAL truncated.
std::uint64_t integer_bits(const ObjectValue& value);

}  // namespace lb::canopen
