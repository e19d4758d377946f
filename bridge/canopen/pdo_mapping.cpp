#include "canopen/pdo_mapping.hpp"

#include <cstring>
#include <string>

namespace lb::canopen {
namespace {

std::uint64_t load_le64(std::span<const std::uint8_t> bytes) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < bytes.size() && i < 8; ++i) v |= std::uint64_t{bytes[i]} << (8 * i);
  return v;
}

std::uint64_t low_bits_mask(unsigned bits) { return bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << bits) - 1; }

}  // namespace

Result<PdoMapping> PdoMapping::create(std::vector<PdoEntry> entries) {
  if (entries.size() > kMaxEntries) return make_error("PDO mapping has more than 64 entries");
  unsigned total = 0;
  for (const auto& e : entries) {
    if (e.bits == 0) return make_error("PDO mapping entry with length 0");
    total += e.bits;
  }
  if (total > 64) {
    return make_error("PDO mapping is " + std::to_string(total) + " bits long; a CAN frame carries 64");
  }
  return PdoMapping(std::move(entries), total);
}

Result<void> PdoMapping::unpack(std::span<const std::uint8_t> payload, Values& out) const {
  if (payload.size() < byte_length()) {
    return make_error("PDO has " + std::to_string(payload.size()) + " bytes, mapping needs " +
                      std::to_string(byte_length()));
  }
  // The whole frame fits in one 64-bit word, so every entry is a shift and a mask.
  const std::uint64_t word = load_le64(payload);
  unsigned offset = 0;
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    const unsigned bits = entries_[i].bits;
    out[i] = offset >= 64 ? 0 : (word >> offset) & low_bits_mask(bits);
    offset += bits;
  }
  return {};
}

std::uint8_t PdoMapping::pack(std::span<const std::uint64_t> values, std::span<std::uint8_t, 8> out) const {
  std::uint64_t word = 0;
  unsigned offset = 0;
  for (std::size_t i = 0; i < entries_.size() && i < values.size(); ++i) {
    const unsigned bits = entries_[i].bits;
    word |= (values[i] & low_bits_mask(bits)) << offset;
    offset += bits;
  }
  for (std::size_t i = 0; i < 8; ++i) out[i] = static_cast<std::uint8_t>(word >> (8 * i));
  return static_cast<std::uint8_t>(byte_length());
}

}  // namespace lb::canopen
