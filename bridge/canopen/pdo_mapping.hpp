#pragma once
// PDO mapping (CiA 301 1600h../1A00h..): which objects a PDO carries, and the codec that packs
// them LSB first, in order, without padding.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "base/result.hpp"

namespace lb::canopen {

struct PdoEntry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint8_t bits = 0;

  // The 32-bit form of a mapping entry: index(16) | sub-index(8) | length(8).
  static constexpr PdoEntry from_u32(std::uint32_t v) {
    return {static_cast<std::uint16_t>(v >> 16), static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v)};
  }
  constexpr std::uint32_t to_u32() const { return std::uint32_t{index} << 16 | std::uint32_t{sub} << 8 | bits; }
  // Indices 0001h..0007h only skip bits (CiA 301 dummy mapping).
  constexpr bool is_dummy() const { return index >= 1 && index <= 7; }
  friend bool operator==(const PdoEntry&, const PdoEntry&) = default;
};

class PdoMapping {
 public:
  static constexpr std::size_t kMaxEntries = 64;
  using Values = std::array<std::uint64_t, kMaxEntries>;

  // Refuses mappings a classical CAN frame cannot carry (more than 64 bits, zero-length entries).
  static Result<PdoMapping> create(std::vector<PdoEntry> entries);
  PdoMapping() = default;

  std::span<const PdoEntry> entries() const { return entries_; }
  unsigned total_bits() const { return total_bits_; }
  unsigned byte_length() const { return (total_bits_ + 7) / 8; }

  // Raw value of every entry, zero-extended, into out[i] for entry i. Fails without touching `out`
  // when the payload is shorter than the mapping; longer payloads are allowed (CiA 301).
  Result<void> unpack(std::span<const std::uint8_t> payload, Values& out) const;
  // Packs values[i] (only its low `bits` bits) for entry i; returns the number of bytes written.
  std::uint8_t pack(std::span<const std::uint64_t> values, std::span<std::uint8_t, 8> out) const;

 private:
  explicit PdoMapping(std::vector<PdoEntry> entries, unsigned total_bits)
      : entries_(std::move(entries)), total_bits_(total_bits) {}

  std::vector<PdoEntry> entries_;
  unsigned total_bits_ = 0;
};

}  // namespace lb::canopen
