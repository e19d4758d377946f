#include "gateways/node/rpdo_read_back.hpp"

#include <fmt/format.h>

#include <array>
#include <memory>

namespace lb::gateways {

namespace {

struct ReadBack {
  canopen::SdoClient& sdo;
  std::uint8_t node;
  canopen::PdoMapping mapping;
  std::vector<bool> read;
  canopen::PdoMapping::Values values{};
  ReadBackDone done;
};

void next(const std::shared_ptr<ReadBack>& rb, std::size_t i) {
  const auto entries = rb->mapping.entries();
  while (i < entries.size() && (entries[i].is_dummy() || (i < rb->read.size() && !rb->read[i]))) ++i;
  if (i == entries.size()) {
    std::array<std::uint8_t, 8> out{};
    const auto n = rb->mapping.pack(std::span<const std::uint64_t>(rb->values.data(), entries.size()), out);
    return rb->done(std::vector<std::uint8_t>(out.begin(), out.begin() + n));
  }
  const auto e = entries[i];
  rb->sdo.upload(rb->node, e.index, e.sub, [rb, i, e](canopen::SdoClient::UploadResult r) {
    if (!r) {
      return rb->done(make_error(fmt::format("{:04X}h sub {} not read back: {}", e.index, e.sub, r.error().message)));
    }
    const auto& bytes = *r;
    if (bytes.size() * 8 < e.bits) {
      return rb->done(make_error(fmt::format("{:04X}h sub {} read back with {} bytes, the mapping has {} bits", e.index,
                                             e.sub, bytes.size(), e.bits)));
    }
    std::uint64_t v = 0;
    for (std::size_t b = 0; b < bytes.size() && b < 8; ++b) v |= std::uint64_t{bytes[b]} << (8 * b);
    rb->values[i] = e.bits >= 64 ? v : v & ((std::uint64_t{1} << e.bits) - 1);
    next(rb, i + 1);
  });
}

}  // namespace

void read_back_rpdo(canopen::SdoClient& sdo, std::uint8_t node, const canopen::PdoMapping& mapping,
                    std::vector<bool> read, std::span<const std::uint8_t> base, ReadBackDone done) {
  auto rb = std::make_shared<ReadBack>(ReadBack{sdo, node, mapping, std::move(read), {}, std::move(done)});
  if (!base.empty()) {
    if (auto ok = mapping.unpack(base, rb->values); !ok) {
      return rb->done(
          make_error("the values kept for its write-only objects do not fit its mapping: " + ok.error().message));
    }
  }
  next(rb, 0);
}

}  // namespace lb::gateways
