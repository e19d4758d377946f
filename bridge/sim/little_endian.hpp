#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

namespace lb::sim {

// An SDO download's bytes as the unsigned value they encode (CiA 301: little-endian; at most 8).
inline std::uint64_t little_endian(std::span<const std::uint8_t> v) {
  std::uint64_t raw = 0;
  for (std::size_t i = 0; i < v.size() && i < 8; ++i) raw |= std::uint64_t{v[i]} << (8 * i);
  return raw;
}

}  // namespace lb::sim
