#pragma once
// The raw values of one device's objects, and PDO mappings bound to them: a received PDO writes
// its entries into the image, a PDO to send is packed from it. Slots are resolved once, so the
// per-frame work is a shift, a mask and a store per entry.

#include <cstdint>
#include <span>
#include <vector>

#include "base/result.hpp"
#include "canopen/pdo_mapping.hpp"

namespace lb::canopen {

class ProcessImage {
 public:
  static constexpr std::size_t npos = static_cast<std::size_t>(-1);

  // The slot of an object, created on first use: at construction, or on the owner's thread before
  // the PDOs that need it are bound (a mapping adopted at boot). Slots never move.
  std::size_t slot(std::uint16_t index, std::uint8_t sub = 0);
  std::size_t find(std::uint16_t index, std::uint8_t sub = 0) const;  // npos when absent
  std::size_t size() const { return values_.size(); }

  std::uint64_t get(std::size_t slot) const { return values_[slot]; }
  void set(std::size_t slot, std::uint64_t raw) { values_[slot] = raw; }

 private:
  struct Key {
    std::uint16_t index;
    std::uint8_t sub;
  };
  std::vector<Key> keys_;
  std::vector<std::uint64_t> values_;
};

class PdoBinding {
 public:
  // Entries of objects not in the image (dummies, manufacturer-specific) are skipped on receive
  // and sent as 0.
  PdoBinding(PdoMapping mapping, const ProcessImage& image);

  const PdoMapping& mapping() const { return mapping_; }
  // Fails, leaving the image untouched, when the payload is shorter than the mapping.
  Result<void> unpack_into(std::span<const std::uint8_t> payload, ProcessImage& image) const;
  std::uint8_t pack_from(const ProcessImage& image, std::span<std::uint8_t, 8> out) const;

 private:
  PdoMapping mapping_;
  std::vector<std::size_t> slots_;
};

}  // namespace lb::canopen
