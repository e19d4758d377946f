// PDO mapping and the process image (canopen/pdo_mapping, process_image) with arbitrary mapping
// entries and payloads: a mapping is refused or packs and unpacks within one classical frame, a
// payload shorter than the mapping changes nothing, and unpack then pack gives back the mapped
// bits of a mapping whose entries are distinct objects.
#include <fuzzer/FuzzedDataProvider.h>

#include <array>
#include <cstdint>
#include <set>
#include <utility>
#include <vector>

#include "canopen/pdo_mapping.hpp"
#include "canopen/process_image.hpp"

using namespace lb::canopen;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  FuzzedDataProvider in(data, size);
  std::vector<PdoEntry> entries(in.ConsumeIntegralInRange<std::size_t>(0, 70));
  for (auto& e : entries) {
    // Mostly few objects and bit lengths a frame can hold, so that mappings pass and get decoded.
    e.index = in.ConsumeBool() ? in.ConsumeIntegralInRange<std::uint16_t>(0, 9) : in.ConsumeIntegral<std::uint16_t>();
    e.sub = in.ConsumeIntegralInRange<std::uint8_t>(0, 3);
    e.bits = in.ConsumeBool() ? in.ConsumeIntegralInRange<std::uint8_t>(0, 65) : in.ConsumeIntegral<std::uint8_t>();
  }
  const auto payload = in.ConsumeBytes<std::uint8_t>(in.ConsumeIntegralInRange<std::size_t>(0, 8));

  auto mapping = PdoMapping::create(entries);
  if (!mapping) return 0;
  if (mapping->total_bits() > 64 || mapping->byte_length() > 8) __builtin_trap();

  ProcessImage image;
  std::set<std::pair<std::uint16_t, std::uint8_t>> objects;
  bool distinct = true;
  for (const auto& e : entries) {
    if (e.is_dummy()) continue;
    image.slot(e.index, e.sub);
    distinct = distinct && objects.emplace(e.index, e.sub).second;
  }
  const PdoBinding binding(*mapping, image);
  const auto unpacked = binding.unpack_into(payload, image);
  if (payload.size() < mapping->byte_length()) {
    if (unpacked) __builtin_trap();
    return 0;
  }
  if (!unpacked) __builtin_trap();
  std::array<std::uint8_t, 8> out{};
  const auto n = binding.pack_from(image, out);
  if (n != mapping->byte_length()) __builtin_trap();
  bool has_dummy = false;
  for (const auto& e : entries) has_dummy = has_dummy || e.is_dummy();
  if (!distinct || has_dummy) return 0;
  // Every mapped bit comes back; bits past the mapping in the last byte are sent as 0.
  for (unsigned bit = 0; bit < mapping->total_bits(); ++bit) {
    const bool sent = (out[bit / 8] >> (bit % 8)) & 1U;
    const bool got = (payload[bit / 8] >> (bit % 8)) & 1U;
    if (sent != got) __builtin_trap();
  }
  for (unsigned bit = mapping->total_bits(); bit < 8 * n; ++bit) {
    if ((out[bit / 8] >> (bit % 8)) & 1U) __builtin_trap();
  }
  return 0;
}
