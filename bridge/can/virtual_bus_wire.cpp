#include "can/virtual_bus_wire.hpp"

#include <cstring>

namespace lb::can::wire {
namespace {

constexpr std::uint32_t kStandardMax = 0x7FF;
constexpr std::uint32_t kExtendedMax = 0x1FFF'FFFF;  // also the error class bits' range (CAN_ERR_MASK)

std::optional<Msg> as_msg(std::span<const std::uint8_t> message) {
  if (message.size() != sizeof(Msg)) return std::nullopt;
  Msg m;
  std::memcpy(&m, message.data(), sizeof m);  // the buffer need not be aligned for Msg
  return m;
}

}  // namespace

Msg encode(const CanFrame& f, std::int64_t now_ns) {
  Msg m{};
  m.id = f.id;
  m.kind = Kind::frame;
  m.flags = static_cast<std::uint8_t>((f.extended ? kFlagExtended : 0) | (f.rtr ? kFlagRtr : 0) |
                                      (f.error ? kFlagError : 0));
  m.len = f.len > CanFrame::kMaxLen ? CanFrame::kMaxLen : f.len;
  std::memcpy(m.data, f.data.data(), m.len);
  m.timestamp_ns = now_ns;
  return m;
}

Msg welcome() {
  Msg m{};
  m.kind = Kind::welcome;
  m.id = kMagic;
  return m;
}

std::optional<CanFrame> decode(std::span<const std::uint8_t> message) {
  const auto m = as_msg(message);
  if (!m || m->kind != Kind::frame || m->len > CanFrame::kMaxLen) return std::nullopt;
  if ((m->flags & ~(kFlagExtended | kFlagRtr | kFlagError)) != 0) return std::nullopt;
  CanFrame f;
  f.extended = (m->flags & kFlagExtended) != 0;
  f.rtr = (m->flags & kFlagRtr) != 0;
  f.error = (m->flags & kFlagError) != 0;
  // Everything above the bus indexes by identifier: one out of range for its format is refused here.
  if (m->id > (f.extended || f.error ? kExtendedMax : kStandardMax)) return std::nullopt;
  if (f.error && (f.extended || f.rtr)) return std::nullopt;
  f.id = m->id;
  f.len = m->len;
  std::memcpy(f.data.data(), m->data, m->len);
  return f;
}

bool is_welcome(std::span<const std::uint8_t> message) {
  const auto m = as_msg(message);
  return m && m->kind == Kind::welcome && m->id == kMagic;
}

}  // namespace lb::can::wire
