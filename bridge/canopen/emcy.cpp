#include "canopen/emcy.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

namespace lb::canopen {

std::optional<Emergency> parse_emergency(const can::CanFrame& frame) {
  if (frame.len != 8) return std::nullopt;
  Emergency e;
  e.error_code = static_cast<std::uint16_t>(frame.data[0] | frame.data[1] << 8);
  e.error_register = frame.data[2];
  std::copy(frame.data.begin() + 3, frame.data.end(), e.manufacturer.begin());
  e.timestamp_ns = frame.timestamp_ns;
  return e;
}

std::string_view emcy_family(std::uint16_t code) {
  // Most specific first: the communication codes share their high byte.
  switch (code) {
    case 0x0000: return "error reset / no error";
    case 0x8110: return "communication: CAN overrun";
    case 0x8120: return "communication: CAN error passive";
    case 0x8130: return "communication: heartbeat or life guard error";
    case 0x8140: return "communication: recovered from bus-off";
    case 0x8150: return "communication: CAN-ID collision";
    case 0x8210: return "protocol: PDO not processed due to length error";
    case 0x8220: return "protocol: PDO length exceeded";
    case 0x8230: return "protocol: DAM MPDO not processed";
    case 0x8240: return "protocol: unexpected SYNC data length";
    case 0x8250: return "protocol: RPDO timeout";
    case 0xFF10: return "device specific: feeder error (CiA 414-2)";
    default: break;
  }
  switch (code >> 12) {
    case 0x1: return "generic error";
    case 0x2: return "current";
    case 0x3: return "voltage";
    case 0x4: return "temperature";
    case 0x5: return "device hardware";
    case 0x6: return "device software";
    case 0x7: return "additional modules";
    case 0x8: return (code >> 8) == 0x81 ? "communication" : (code >> 8) == 0x82 ? "protocol error" : "monitoring";
    case 0x9: return "external error";
    case 0xF: return (code >> 8) == 0xFF ? "device specific" : "additional functions";
    default: return "unknown family";
  }
}

EmcyClass emcy_class(std::uint16_t code) {
  const unsigned high = code >> 8;
  switch (code >> 12) {
    case 0x0: return high == 0x00 ? EmcyClass::error_reset : EmcyClass::other;
    case 0x1: return high == 0x10 ? EmcyClass::generic : EmcyClass::other;
    case 0x2: return EmcyClass::current;
    case 0x3: return EmcyClass::voltage;
    case 0x4: return EmcyClass::temperature;
    case 0x5: return EmcyClass::device_hardware;
    case 0x6: return EmcyClass::device_software;
    case 0x7: return EmcyClass::additional_modules;
    case 0x8:
      return high == 0x81 ? EmcyClass::communication : high == 0x82 ? EmcyClass::protocol : EmcyClass::monitoring;
    case 0x9: return EmcyClass::external;
    case 0xF: return high == 0xFF ? EmcyClass::device_specific : EmcyClass::additional_functions;
    default: return EmcyClass::other;
  }
}

std::string_view to_string(EmcyClass c) {
  switch (c) {
    case EmcyClass::error_reset: return "error_reset";
    case EmcyClass::generic: return "generic";
    case EmcyClass::current: return "current";
    case EmcyClass::voltage: return "voltage";
    case EmcyClass::temperature: return "temperature";
    case EmcyClass::device_hardware: return "device_hardware";
    case EmcyClass::device_software: return "device_software";
    case EmcyClass::additional_modules: return "additional_modules";
    case EmcyClass::communication: return "communication";
    case EmcyClass::protocol: return "protocol";
    case EmcyClass::monitoring: return "monitoring";
    case EmcyClass::external: return "external";
    case EmcyClass::additional_functions: return "additional_functions";
    case EmcyClass::device_specific: return "device_specific";
    case EmcyClass::other: break;
  }
  return "other";
}

void ActiveErrors::apply(const Emergency& e) {
  error_register_ = e.error_register;
  // CiA 301: the error register is 0 exactly when no error is active, whatever the code says.
  if (e.error_register == 0) return clear();
  if (!e.is_reset()) {
    if (known_) note_.clear();  // a note on codes cleared before is about earlier EMCYs
    return add(e.error_code);
  }
  // "Error reset" while the register still reports errors: some were cleared, others remain.
  known_ = false;
  reset_left_errors_ = true;
  note_ = fmt::format("EMCY 0000h (error reset) with error register {:02X}h: errors remain and the EMCY does not say "
                      "which",
                      e.error_register);
}

void ActiveErrors::reset_by_boot_up() { clear(); }

std::vector<std::uint16_t> ActiveErrors::checked_after_emcy(std::uint8_t error_register) {
  if (error_register != 0) {
    reconcile(error_register);
    return {};
  }
  auto contradicted = codes_;
  clear();
  if (!contradicted.empty()) {
    note_ = fmt::format("EMCY {:04X}h cleared: the device's own error register 1001h read 00h after it (an error "
                        "gone by then, or an EMCY the device never sent: CAN frames are not authenticated)",
                        fmt::join(contradicted, " "));
  }
  return contradicted;
}

void ActiveErrors::reconcile(std::uint8_t error_register) {
  if (error_register == 0) return clear();
  error_register_ = error_register;
  if (known_ && !codes_.empty()) return;  // the EMCYs since the boot-up name them; the register agrees
  if (reset_left_errors_) return;         // uncertain already, and the note says why
  // 1003h cannot help: it is the history, it does not say which of its entries are still active.
  known_ = false;
  note_ = fmt::format("error register 1001h = {:02X}h: errors are active that no EMCY since the device's boot-up "
                      "named (raised before the bridge heard it); which ones is unknown (1003h is the device's "
                      "error history, on info, not its active errors)",
                      error_register);
}

void ActiveErrors::clear() {
  codes_.clear();
  error_register_ = 0;
  known_ = true;
  reset_left_errors_ = false;
  note_.clear();
}

void ActiveErrors::mark_uncertain(std::string why, std::optional<std::uint8_t> error_register) {
  if (error_register) error_register_ = *error_register;
  known_ = false;
  note_ = std::move(why);
}

void ActiveErrors::add(std::uint16_t code) {
  if (std::find(codes_.begin(), codes_.end(), code) == codes_.end() && codes_.size() < kMax) codes_.push_back(code);
}

}  // namespace lb::canopen
