#pragma once
// Emergency messages (CiA 301 EMCY, 080h + node-ID): decoding, the error code's family in words,
// and the set of a device's active errors.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
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

// The errors a device has raised and not cleared, and whether that list can be trusted (CiA 301):
//   - an EMCY with a code adds it;
//   - an EMCY 0000h ("error reset or no error") clears the list only when the error register it
//     carries is 0; with a register other than 0 errors remain and the EMCY does not say which:
//     the list is uncertain until the device says (1003h, pre-defined error field) or clears all;
//   - a boot-up clears it: the device starts without active errors;
//   - what the device lists in 1003h (read by the master) replaces it.
// Until one of these happened (a monitor that joined a running line, a master before its first
// read) the list is uncertain too: errors raised before cannot be known.
class ActiveErrors {
 public:
  static constexpr std::size_t kMax = 16;  // matches the DDS bound; further codes are dropped

  void apply(const Emergency& e);
  void reset_by_boot_up();
  // The device's own list (codes oldest first) and its error register 1001h.
  void replace(std::vector<std::uint16_t> codes, std::uint8_t error_register, std::string note);
  // The list cannot be trusted: kept as it is, flagged, with the reason (and the register, if read).
  void mark_uncertain(std::string why, std::optional<std::uint8_t> error_register = std::nullopt);

  const std::vector<std::uint16_t>& codes() const { return codes_; }
  std::uint8_t error_register() const { return error_register_; }
  bool known() const { return known_; }
  // Why the list is uncertain, or where it comes from when that is worth saying; may be empty.
  const std::string& note() const { return note_; }
  // An error reset whose register says errors remain: the master should read 1003h.
  bool needs_reading() const { return needs_reading_; }

 private:
  void add(std::uint16_t code);

  std::vector<std::uint16_t> codes_;
  std::uint8_t error_register_ = 0;
  bool known_ = false;
  bool needs_reading_ = false;
  std::string note_ = "not known yet: no boot-up seen and the device's errors not read";
};

}  // namespace lb::canopen
