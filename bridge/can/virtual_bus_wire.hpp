#pragma once
// The virtual bus's wire format: one fixed-size message per frame (or hub welcome) on a hub
// connection. Any process on the machine can connect to a hub and send any bytes, so what arrives
// is checked before it becomes a CanFrame: a message that is not exactly one well-formed frame is
// dropped, never trusted.

#include <cstdint>
#include <optional>
#include <span>
#include <type_traits>

#include "can/can_frame.hpp"

namespace lb::can::wire {

// In the welcome message: a member never talks to a hub with another wire format.
inline constexpr std::uint32_t kMagic = 0x4C42'5601;  // "LBV", version 1

enum class Kind : std::uint8_t { frame = 0, welcome = 1 };
enum : std::uint8_t { kFlagExtended = 1, kFlagRtr = 2, kFlagError = 4 };

// Members and hub are on one machine, so host byte order is fine.
struct Msg {
  std::uint32_t id;
  Kind kind;
  std::uint8_t flags;
  std::uint8_t len;
  std::uint8_t reserved;
  std::uint8_t data[CanFrame::kMaxLen];
  std::int64_t timestamp_ns;  // sender's CLOCK_REALTIME at send: the receiver's frame stamp, if plausible
};
static_assert(sizeof(Msg) == 24 && std::is_trivially_copyable_v<Msg>);

Msg encode(const CanFrame& frame, std::int64_t now_ns);
Msg welcome();
// The frame a received message carries (timestamp_ns 0: the receiver decides), or nullopt for
// anything else: a welcome, a message of another size, a length over 8, unknown flags, an
// identifier its format cannot have.
std::optional<CanFrame> decode(std::span<const std::uint8_t> message);
// Whether a received message is a welcome of this wire format version.
bool is_welcome(std::span<const std::uint8_t> message);

}  // namespace lb::can::wire
