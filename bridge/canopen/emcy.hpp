#pragma once
// Emergency messages (CiA 301 EMCY, 080h + node-ID): decoding, the error code's family in words,
// and the set of a device's active errors.

#include <array>
#include <cstddef>
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

// The class of an EMCY code, by its high byte as CiA 301's table of error codes groups them: a
// small fixed set, so that a count per class is a bounded set of counters (diagnostics, metrics).
// 00xxh error reset, 10xxh generic, 2xxxh current, 3xxxh voltage, 4xxxh temperature, 5xxxh device
// hardware, 6xxxh device software, 7xxxh additional modules, 81xxh communication, 82xxh protocol
// error, other 8xxxh monitoring, 9xxxh external, F0xxh..FExxh additional functions, FFxxh device
// specific; anything else (01xxh..0Fxxh, 11xxh..1Fxxh, Axxxh..Exxxh) "other".
enum class EmcyClass : std::uint8_t {
  error_reset,
  generic,
  current,
  voltage,
  temperature,
  device_hardware,
  device_software,
  additional_modules,
  communication,
  protocol,
  monitoring,
  external,
  additional_functions,
  device_specific,
  other,
};
inline constexpr std::size_t kEmcyClasses = static_cast<std::size_t>(EmcyClass::other) + 1;
EmcyClass emcy_class(std::uint16_t error_code);
// As a metric's label spells it: "error_reset", "generic", ..., "device_specific", "other".
std::string_view to_string(EmcyClass c);

// The errors a device has active now, and whether that list can be trusted (CiA 301). Only the
// EMCYs received since the device's last boot-up and its error register (1001h) say that; 1003h,
// the pre-defined error field, is the device's error HISTORY (every EMCY it sent, error resets
// included) and never feeds this list (error_field.hpp reads it as history):
//   - an EMCY with a code and an error register other than 0 adds the code;
//   - an EMCY whose error register is 0 leaves nothing active: the register says no error is
//     (an EMCY 0000h "error reset or no error" with register 0, or a code sent as a mere event);
//   - an EMCY 0000h with a register other than 0: some errors were cleared, others remain, and the
//     EMCY does not say which: the list is uncertain until the register goes to 0 or a boot-up;
//   - a boot-up clears it: the device starts without active errors;
//   - the register read by the master (reconcile): 0 clears it; otherwise the list stays, and it
//     is uncertain when no EMCY since the boot-up names an error that the register reports;
//   - the register read again because an EMCY came while the device ran (checked_after_emcy): 0
//     clears it too, with a note naming the codes the device's own register contradicts. CAN is
//     not authenticated: any bus member can send an EMCY in a device's name, and only the device
//     can say it has no error. A forged EMCY while the device has a real error is not told apart.
// Until one of these happened (a monitor that joined a running line, a master before its first
// read) the list is uncertain too: errors raised before cannot be known.
class ActiveErrors {
 public:
  static constexpr std::size_t kMax = 16;  // matches the DDS bound; further codes are dropped

  void apply(const Emergency& e);
  void reset_by_boot_up();
  // The device's error register 1001h as the master read it.
  void reconcile(std::uint8_t error_register);
  // The same, read because an EMCY came while the device was operational: 0 clears the list and
  // the note says which codes the device's own register contradicts. Returns those codes.
  std::vector<std::uint16_t> checked_after_emcy(std::uint8_t error_register);
  // The list cannot be trusted: kept as it is, flagged, with the reason (and the register, if read).
  void mark_uncertain(std::string why, std::optional<std::uint8_t> error_register = std::nullopt);

  const std::vector<std::uint16_t>& codes() const { return codes_; }
  std::uint8_t error_register() const { return error_register_; }
  bool known() const { return known_; }
  // Why the list is uncertain, or where it comes from when that is worth saying; may be empty.
  const std::string& note() const { return note_; }

 private:
  void add(std::uint16_t code);
  void clear();

  std::vector<std::uint16_t> codes_;
  std::uint8_t error_register_ = 0;
  bool known_ = false;
  bool reset_left_errors_ = false;  // uncertain because of an EMCY 0000h with a register other than 0
  std::string note_ = "not known yet: no boot-up seen and the device's error register not read";
};

}  // namespace lb::canopen
