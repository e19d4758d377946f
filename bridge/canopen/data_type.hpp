#pragma once
// CiA 301 basic data types, as far as object values and PDO mapping need them.

#include <cstdint>
#include <optional>
#include <string_view>

namespace lb::canopen {

enum class DataType : std::uint8_t {
  boolean,
  integer8,
  integer16,
  integer32,
  integer64,
  unsigned8,
  unsigned16,
  unsigned32,
  unsigned64,
  real32,
  real64,
  visible_string,
  octet_string,
};

// Size in bits of a fixed-size type; 0 for strings.
unsigned bit_size(DataType type);
bool is_signed_integer(DataType type);
bool is_unsigned_integer(DataType type);
std::string_view to_string(DataType type);  // CiA 301 spelling, e.g. "UNSIGNED16"
std::optional<DataType> parse_data_type(std::string_view name);

// Smallest and largest raw value a fixed-size integer type can hold.
std::int64_t type_min(DataType type);
std::uint64_t type_max(DataType type);

// Interprets the low `bits` bits of raw as a two's-complement number.
constexpr std::int64_t sign_extend(std::uint64_t raw, unsigned bits) {
  if (bits == 0 || bits >= 64) return static_cast<std::int64_t>(raw);
  const std::uint64_t sign = std::uint64_t{1} << (bits - 1);
  const std::uint64_t value = raw & ((std::uint64_t{1} << bits) - 1);
  return static_cast<std::int64_t>((value ^ sign) - sign);
}

}  // namespace lb::canopen
