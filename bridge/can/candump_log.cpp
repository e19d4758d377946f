#include "can/candump_log.hpp"

#include <linux/can.h>

#include <cctype>
#include <cstdio>
#include <limits>
#include <vector>

namespace lb::can {
namespace {

std::optional<unsigned> hex_digit(char c) {
  if (c >= '0' && c <= '9') return static_cast<unsigned>(c - '0');
  if (c >= 'A' && c <= 'F') return static_cast<unsigned>(c - 'A' + 10);
  if (c >= 'a' && c <= 'f') return static_cast<unsigned>(c - 'a' + 10);
  return std::nullopt;
}

std::optional<std::uint64_t> decimal(std::string_view s) {
  if (s.empty() || s.size() > 18) return std::nullopt;
  std::uint64_t v = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return std::nullopt;
    v = v * 10 + static_cast<std::uint64_t>(c - '0');
  }
  return v;
}

std::vector<std::string_view> fields(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])) != 0) ++i;
    const std::size_t start = i;
    while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i])) == 0) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

// "(seconds.fraction)"; the fraction has 6 digits in candump's output, any 1..9 are accepted.
std::optional<std::int64_t> parse_timestamp(std::string_view t) {
  if (t.size() < 4 || t.front() != '(' || t.back() != ')') return std::nullopt;
  t = t.substr(1, t.size() - 2);
  const auto dot = t.find('.');
  if (dot == std::string_view::npos) return std::nullopt;
  const auto sec = decimal(t.substr(0, dot));
  const std::string_view frac = t.substr(dot + 1);
  const auto sub = decimal(frac);
  // Beyond this many seconds (the year 2262) the time does not fit the nanoseconds a frame carries.
  constexpr std::uint64_t kMaxSeconds = std::numeric_limits<std::int64_t>::max() / 1'000'000'000 - 1;
  if (!sec || !sub || frac.size() > 9 || *sec > kMaxSeconds) return std::nullopt;
  std::int64_t ns = static_cast<std::int64_t>(*sub);
  for (std::size_t i = frac.size(); i < 9; ++i) ns *= 10;
  return static_cast<std::int64_t>(*sec) * 1'000'000'000 + ns;
}

Result<CanFrame> parse_frame(std::string_view text) {
  const auto fail = [&](const std::string& why) { return make_error("'" + std::string(text) + "': " + why); };
  const auto hash = text.find('#');
  if (hash == std::string_view::npos) return fail("no '#' between identifier and data");
  const std::string_view id_text = text.substr(0, hash);
  std::string_view rest = text.substr(hash + 1);
  if (!rest.empty() && rest.front() == '#') return fail("CAN FD frame (only classical CAN is supported)");
  if (id_text.size() != 3 && id_text.size() != 8) {
    return fail("the identifier must have 3 (11-bit) or 8 (29-bit, error frame) hex digits");
  }
  std::uint32_t id = 0;
  for (char c : id_text) {
    const auto d = hex_digit(c);
    if (!d) return fail("the identifier is not hexadecimal");
    id = id << 4 | *d;
  }
  CanFrame frame;
  if (id_text.size() == 3) {
    if (id > CAN_SFF_MASK) return fail("an 11-bit identifier is at most 7FF");
    frame.id = id;
  } else if ((id & CAN_ERR_FLAG) != 0) {
    frame.error = true;
    frame.id = id & CAN_ERR_MASK;
  } else {
    if (id > CAN_EFF_MASK) return fail("a 29-bit identifier is at most 1FFFFFFF");
    frame.extended = true;
    frame.id = id;
  }
  // "_X" after the data is the raw DLC 9..F of an 8-byte frame (candump -8): the data says it all.
  if (const auto us = rest.find('_'); us != std::string_view::npos) rest = rest.substr(0, us);

  if (!rest.empty() && (rest.front() == 'R' || rest.front() == 'r')) {
    if (frame.error) return fail("an error frame cannot be a remote frame");
    frame.rtr = true;
    rest.remove_prefix(1);
    if (rest.size() > 1) return fail("a remote frame carries at most one length digit");
    if (rest.size() == 1) {
      const auto d = hex_digit(rest.front());
      if (!d || *d > CanFrame::kMaxLen) return fail("the remote frame's length must be 0..8");
      frame.len = static_cast<std::uint8_t>(*d);
    }
    return frame;
  }
  for (std::size_t i = 0; i < rest.size();) {
    if (rest[i] == '.') {  // cansend's optional byte separator
      ++i;
      continue;
    }
    if (i + 1 >= rest.size()) return fail("odd number of hex digits in the data");
    const auto hi = hex_digit(rest[i]);
    const auto lo = hex_digit(rest[i + 1]);
    if (!hi || !lo) return fail("the data is not hexadecimal");
    if (frame.len == CanFrame::kMaxLen) return fail("more than 8 data bytes");
    frame.data[frame.len++] = static_cast<std::uint8_t>(*hi << 4 | *lo);
    i += 2;
  }
  return frame;
}

}  // namespace

std::string format_log_line(const CanFrame& frame, std::string_view interface) {
  std::string line;
  append_log_line(line, frame, interface);
  return line;
}

void append_log_line(std::string& line, const CanFrame& frame, std::string_view interface) {
  char buf[96];
  const std::int64_t ns = frame.timestamp_ns < 0 ? 0 : frame.timestamp_ns;
  int n = std::snprintf(buf, sizeof buf, "(%010lld.%06lld) ", static_cast<long long>(ns / 1'000'000'000),
                        static_cast<long long>(ns % 1'000'000'000 / 1000));
  line.append(buf, static_cast<std::size_t>(n));
  line.append(interface);
  if (frame.error) {
    n = std::snprintf(buf, sizeof buf, " %08X#", static_cast<unsigned>((frame.id & CAN_ERR_MASK) | CAN_ERR_FLAG));
  } else if (frame.extended) {
    n = std::snprintf(buf, sizeof buf, " %08X#", static_cast<unsigned>(frame.id & CAN_EFF_MASK));
  } else {
    n = std::snprintf(buf, sizeof buf, " %03X#", static_cast<unsigned>(frame.id & CAN_SFF_MASK));
  }
  line.append(buf, static_cast<std::size_t>(n));
  const std::uint8_t len = frame.len > CanFrame::kMaxLen ? CanFrame::kMaxLen : frame.len;
  if (frame.rtr && !frame.error) {
    line += 'R';
    if (len > 0) line += static_cast<char>('0' + len);
  } else {
    for (std::uint8_t i = 0; i < len; ++i) {
      std::snprintf(buf, sizeof buf, "%02X", static_cast<unsigned>(frame.data[i]));
      line.append(buf, 2);
    }
  }
  line += '\n';
}

Result<std::optional<LogRecord>> parse_log_line(std::string_view line) {
  const auto f = fields(line);
  if (f.empty()) return std::optional<LogRecord>{};
  if (f.size() < 3) return make_error("'" + std::string(line) + "': expected (timestamp) interface frame");
  const auto ts = parse_timestamp(f[0]);
  if (!ts) return make_error("'" + std::string(f[0]) + "': the timestamp must be (seconds.microseconds)");
  auto frame = parse_frame(f[2]);
  if (!frame) return frame.error();
  frame->timestamp_ns = *ts;
  return std::optional<LogRecord>{LogRecord{std::string(f[1]), *frame}};
}

}  // namespace lb::can
