#pragma once
// One classical CAN frame as every layer above the bus sees it.

#include <array>
#include <cstdint>
#include <span>

namespace lb::can {

struct CanFrame {
  static constexpr std::uint8_t kMaxLen = 8;

  std::uint32_t id = 0;  // 11- or 29-bit identifier; for error frames the SocketCAN error class bits
  bool extended = false;
  bool rtr = false;
  bool error = false;  // error frame reported by the controller (data as SocketCAN's <linux/can/error.h>)
  std::uint8_t len = 0;
  std::array<std::uint8_t, kMaxLen> data{};
  std::int64_t timestamp_ns = 0;  // CLOCK_REALTIME when on the bus: SocketCAN the kernel's receive stamp, virtual: the
                                  // send (0 for frames to send)

  std::span<const std::uint8_t> payload() const { return {data.data(), len}; }
};

// Convenience for building frames in code and tests: CanFrame f = make_frame(0x203, {0x01, 0x02}).
inline CanFrame make_frame(std::uint32_t id, std::initializer_list<std::uint8_t> bytes) {
  CanFrame f;
  f.id = id;
  for (auto b : bytes) {
    if (f.len == CanFrame::kMaxLen) break;
    f.data[f.len++] = b;
  }
  return f;
}

}  // namespace lb::can
