// The candump log parser (can/candump_log), which reads `log:` replays and recordings: any line is
// a frame, a blank or an error, never a crash; a frame it accepts is a classical CAN frame, and
// formatting it and parsing that again gives the same frame.
#include <cstdint>
#include <string_view>

#include "can/candump_log.hpp"

using namespace lb::can;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view line(reinterpret_cast<const char*>(data), size);
  const auto parsed = parse_log_line(line);
  if (!parsed || !*parsed) return 0;
  const CanFrame& f = (*parsed)->frame;
  if (f.len > CanFrame::kMaxLen) __builtin_trap();
  if (!f.error && f.id > (f.extended ? 0x1FFF'FFFFU : 0x7FFU)) __builtin_trap();
  if (f.timestamp_ns < 0) __builtin_trap();
  const auto again = parse_log_line(format_log_line(f, (*parsed)->interface));
  if (!again || !*again) __builtin_trap();
  const CanFrame& g = (*again)->frame;
  if (g.id != f.id || g.extended != f.extended || g.rtr != f.rtr || g.error != f.error || g.len != f.len ||
      g.timestamp_ns / 1000 != f.timestamp_ns / 1000 || (*again)->interface != (*parsed)->interface) {
    __builtin_trap();
  }
  if (!f.rtr && g.payload().size() == f.payload().size()) {
    for (std::size_t i = 0; i < f.len; ++i) {
      if (g.data[i] != f.data[i]) __builtin_trap();
    }
  }
  return 0;
}
