#include "canopen/process_image.hpp"

namespace lb::canopen {

std::size_t ProcessImage::slot(std::uint16_t index, std::uint8_t sub) {
  if (const auto s = find(index, sub); s != npos) return s;
  keys_.push_back({index, sub});
  values_.push_back(0);
  return values_.size() - 1;
}

std::size_t ProcessImage::find(std::uint16_t index, std::uint8_t sub) const {
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    if (keys_[i].index == index && keys_[i].sub == sub) return i;
  }
  return npos;
}

PdoBinding::PdoBinding(PdoMapping mapping, const ProcessImage& image) : mapping_(std::move(mapping)) {
  for (const auto& e : mapping_.entries())
    slots_.push_back(e.is_dummy() ? ProcessImage::npos : image.find(e.index, e.sub));
}

Result<void> PdoBinding::unpack_into(std::span<const std::uint8_t> payload, ProcessImage& image) const {
  PdoMapping::Values values;
  if (auto r = mapping_.unpack(payload, values); !r) return r;
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    if (slots_[i] != ProcessImage::npos) image.set(slots_[i], values[i]);
  }
  return {};
}

std::uint8_t PdoBinding::pack_from(const ProcessImage& image, std::span<std::uint8_t, 8> out) const {
  PdoMapping::Values values{};
  for (std::size_t i = 0; i < slots_.size(); ++i) {
    if (slots_[i] != ProcessImage::npos) values[i] = image.get(slots_[i]);
  }
  return mapping_.pack(std::span<const std::uint64_t>(values.data(), slots_.size()), out);
}

}  // namespace lb::canopen
