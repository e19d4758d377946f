#include "canopen/object_value.hpp"

#include <fmt/format.h>

#include <bit>
#include <cmath>
#include <limits>
#include <type_traits>

namespace lb::canopen {
namespace {

std::string_view kind(const ObjectValue& value) {
  constexpr std::string_view kKinds[] = {"a signed integer", "an unsigned integer", "a real number", "a string",
                                         "a byte string"};
  return kKinds[value.index()];
}

Error mismatch(DataType type, const ObjectValue& value) {
  return make_error(fmt::format("{} cannot take {} ({})", to_string(type), kind(value), to_string(value)));
}

std::vector<std::uint8_t> little_endian(std::uint64_t raw, std::size_t size) {
  std::vector<std::uint8_t> bytes(size);
  for (std::size_t i = 0; i < size; ++i) bytes[i] = static_cast<std::uint8_t>(raw >> (8 * i));
  return bytes;
}

Result<std::vector<std::uint8_t>> encode_integer(DataType type, const ObjectValue& value) {
  const std::size_t size = sdo_size(type);
  const std::int64_t lo = type_min(type);
  const std::uint64_t hi = type_max(type);
  if (const auto* s = std::get_if<std::int64_t>(&value)) {
    const bool fits = *s < 0 ? *s >= lo : static_cast<std::uint64_t>(*s) <= hi;
    if (!fits) return make_error(fmt::format("{} is out of range for {} ({}..{})", *s, to_string(type), lo, hi));
    return little_endian(static_cast<std::uint64_t>(*s), size);
  }
  if (const auto* u = std::get_if<std::uint64_t>(&value)) {
    if (*u > hi) return make_error(fmt::format("{} is out of range for {} ({}..{})", *u, to_string(type), lo, hi));
    return little_endian(*u, size);
  }
  return mismatch(type, value);
}

Result<std::vector<std::uint8_t>> encode_real(DataType type, const ObjectValue& value) {
  double d = 0;
  if (const auto* r = std::get_if<double>(&value)) {
    d = *r;
  } else if (const auto* s = std::get_if<std::int64_t>(&value)) {
    d = static_cast<double>(*s);
  } else if (const auto* u = std::get_if<std::uint64_t>(&value)) {
    d = static_cast<double>(*u);
  } else {
    return mismatch(type, value);
  }
  if (type == DataType::real64) return little_endian(std::bit_cast<std::uint64_t>(d), 8);
  // Infinities and NaN are REAL32 values; a finite number beyond float's range is not.
  if (std::isfinite(d) && std::fabs(d) > std::numeric_limits<float>::max()) {
    return make_error(fmt::format("{} is out of range for REAL32", d));
  }
  return little_endian(std::bit_cast<std::uint32_t>(static_cast<float>(d)), 4);
}

}  // namespace

std::size_t sdo_size(DataType type) {
  if (type == DataType::boolean) return 1;
  return bit_size(type) / 8;
}

Result<std::vector<std::uint8_t>> encode(DataType type, const ObjectValue& value) {
  switch (type) {
    case DataType::visible_string:
      if (const auto* s = std::get_if<std::string>(&value)) return std::vector<std::uint8_t>(s->begin(), s->end());
      return mismatch(type, value);
    case DataType::octet_string:
      if (const auto* b = std::get_if<std::vector<std::uint8_t>>(&value)) return *b;
      if (const auto* s = std::get_if<std::string>(&value)) return std::vector<std::uint8_t>(s->begin(), s->end());
      return mismatch(type, value);
    case DataType::real32:
    case DataType::real64: return encode_real(type, value);
    default: return encode_integer(type, value);
  }
}

Result<ObjectValue> decode(DataType type, std::span<const std::uint8_t> bytes) {
  if (type == DataType::visible_string) {
    std::string s(bytes.begin(), bytes.end());
    s.resize(std::min(s.size(), s.find('\0')));
    return ObjectValue{std::move(s)};
  }
  if (type == DataType::octet_string) return ObjectValue{std::vector<std::uint8_t>(bytes.begin(), bytes.end())};
  const std::size_t size = sdo_size(type);
  if (bytes.size() != size) {
    return make_error(fmt::format("{} takes {} bytes, got {}", to_string(type), size, bytes.size()));
  }
  std::uint64_t raw = 0;
  for (std::size_t i = 0; i < size; ++i) raw |= std::uint64_t{bytes[i]} << (8 * i);
  if (type == DataType::real32) return ObjectValue{double{std::bit_cast<float>(static_cast<std::uint32_t>(raw))}};
  if (type == DataType::real64) return ObjectValue{std::bit_cast<double>(raw)};
  if (is_signed_integer(type)) return ObjectValue{sign_extend(raw, bit_size(type))};
  if (type == DataType::boolean && raw > 1) return make_error(fmt::format("BOOLEAN is 0 or 1, got {}", raw));
  return ObjectValue{raw};
}

std::string to_string(const ObjectValue& value) {
  return std::visit(
      [](const auto& v) -> std::string {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, std::string>) {
          std::string out = "\"";
          for (const char c : v) {
            const auto u = static_cast<unsigned char>(c);
            if (c == '"' || c == '\\') {
              out += '\\';
              out += c;
            } else if (u < 0x20 || u > 0x7E) {
              out += fmt::format("\\x{:02X}", u);
            } else {
              out += c;
            }
          }
          return out + "\"";
        } else if constexpr (std::is_same_v<T, std::vector<std::uint8_t>>) {
          std::string out = "[";
          for (std::size_t i = 0; i < v.size(); ++i) out += fmt::format("{}{:02X}", i == 0 ? "" : " ", v[i]);
          return out + "]";
        } else {
          return fmt::format("{}", v);
        }
      },
      value);
}

std::uint64_t integer_bits(const ObjectValue& value) {
  if (const auto* u = std::get_if<std::uint64_t>(&value)) return *u;
  if (const auto* i = std::get_if<std::int64_t>(&value)) return static_cast<std::uint64_t>(*i);
  if (const auto* d = std::get_if<double>(&value)) return static_cast<std::uint64_t>(static_cast<std::int64_t>(*d));
  return 0;
}

}  // namespace lb::canopen
