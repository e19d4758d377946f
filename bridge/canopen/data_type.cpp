#include "canopen/data_type.hpp"

#include <array>
#include <limits>

namespace lb::canopen {
namespace {

struct TypeInfo {
  DataType type;
  std::string_view name;
  unsigned bits;
};

constexpr std::array<TypeInfo, 13> kTypes{{
    {DataType::boolean, "BOOLEAN", 1},
    {DataType::integer8, "INTEGER8", 8},
    {DataType::integer16, "INTEGER16", 16},
    {DataType::integer32, "INTEGER32", 32},
    {DataType::integer64, "INTEGER64", 64},
    {DataType::unsigned8, "UNSIGNED8", 8},
    {DataType::unsigned16, "UNSIGNED16", 16},
    {DataType::unsigned32, "UNSIGNED32", 32},
    {DataType::unsigned64, "UNSIGNED64", 64},
    {DataType::real32, "REAL32", 32},
    {DataType::real64, "REAL64", 64},
    {DataType::visible_string, "VISIBLE_STRING", 0},
    {DataType::octet_string, "OCTET_STRING", 0},
}};

const TypeInfo& info(DataType type) { return kTypes[static_cast<std::size_t>(type)]; }

}  // namespace

unsigned bit_size(DataType type) { return info(type).bits; }

bool is_signed_integer(DataType type) {
  return type == DataType::integer8 || type == DataType::integer16 || type == DataType::integer32 ||
         type == DataType::integer64;
}

bool is_unsigned_integer(DataType type) {
  return type == DataType::boolean || type == DataType::unsigned8 || type == DataType::unsigned16 ||
         type == DataType::unsigned32 || type == DataType::unsigned64;
}

std::string_view to_string(DataType type) { return info(type).name; }

std::optional<DataType> parse_data_type(std::string_view name) {
  for (const auto& t : kTypes) {
    if (t.name == name) return t.type;
  }
  return std::nullopt;
}

std::int64_t type_min(DataType type) {
  if (!is_signed_integer(type)) return 0;
  const unsigned bits = bit_size(type);
  return bits >= 64 ? std::numeric_limits<std::int64_t>::min() : -(std::int64_t{1} << (bits - 1));
}

std::uint64_t type_max(DataType type) {
  const unsigned bits = bit_size(type);
  if (bits == 0) return 0;
  if (is_signed_integer(type)) return (std::uint64_t{1} << (bits - 1)) - 1;
  return bits >= 64 ? std::numeric_limits<std::uint64_t>::max() : (std::uint64_t{1} << bits) - 1;
}

}  // namespace lb::canopen
