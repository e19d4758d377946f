#pragma once
// can-utils' log format, the one `candump -l` writes and `canplayer` reads, one frame per line:
//   (1700000000.123456) vcan0 183#0200785634120000
//   (1700000000.123789) vcan0 12345678#DEAD        29-bit identifier: always 8 hex digits
//   (1700000000.124000) vcan0 701#R                remote frame (R4: with a length of 4)
//   (1700000000.125000) vcan0 20000040#0000000000000000   error frame: CAN_ERR_FLAG | class bits
// Recordings made here replay in canplayer, and candump's replay here.

#include <optional>
#include <string>
#include <string_view>

#include "base/result.hpp"
#include "can/can_frame.hpp"

namespace lb::can {

struct LogRecord {
  std::string interface;  // the interface name in the line (vcan0, can0, ...)
  CanFrame frame;         // timestamp_ns is the recorded time
};

// The line for one frame, newline included. interface must not contain blanks.
std::string format_log_line(const CanFrame& frame, std::string_view interface);
// The same, appended to out: a caller that keeps out's capacity formats without allocating.
void append_log_line(std::string& out, const CanFrame& frame, std::string_view interface);

// One line, trailing newline or not. std::nullopt for a blank line; an error for anything else
// that is not a classical CAN frame (CAN FD "##" lines included: this gateway speaks classical
// CAN only). Fields after the frame (candump -x adds a direction) are ignored.
Result<std::optional<LogRecord>> parse_log_line(std::string_view line);

}  // namespace lb::can
