#pragma once
// Emergency messages (CiA 301 EMCY, 080h + node-ID): decoding, the error code's family in words,
// and the set of a device's active errors.

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "can/can_frame.hpp"

namespace lb::canopen {

struct Emergency {
  std::uint16_t error_code = 0;  // 0000h: error reset / no error
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer{};
  std::int64_t timestamp_ns = 0;

  bool is_reset() const { return error_code == 0; }
};

// std::nullopt for a frame that is not 8 bytes long (CiA 301 fixes the EMCY length).
std::optional<Emergency> parse_emergency(const can::CanFrame& frame);

// "generic", "current", "voltage", "temperature", "communication: heartbeat or life guard", ...
std::string_view emcy_family(std::uint16_t error_code);

// Errors raised and not yet cleared. An EMCY 0000h (error reset) clears them all, as a device
// sends it when it has no error left (CiA 301).
class ActiveErrors {
 public:
  static constexpr std::size_t kMax = 16;  // matches the DDS bound; further codes are dropped

  void apply(const Emergency& e);
  const std::vector<std::uint16_t>& codes() const { return codes_; }
  std::uint8_t error_register() const { return error_register_; }

 private:
  std::vector<std::uint16_t> codes_;
  std::uint8_t error_register_ = 0;
};

}  // namespace lb::canopen
