#pragma once
// Small helpers shared by the bus implementations; not part of the layer's interface.

#include <sys/epoll.h>

#include <cstdint>
#include <cstdio>
#include <ctime>
#include <string>
#include <string_view>
#include <system_error>

#include "base/result.hpp"
#include "can/can_frame.hpp"

namespace lb::can::detail {

// Level-triggered readability of fd, reported with fd as its data.
inline bool epoll_add(int epoll_fd, int fd) {
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.fd = fd;
  return ::epoll_ctl(epoll_fd, EPOLL_CTL_ADD, fd, &ev) == 0;
}

inline std::string errno_text(int err) { return std::generic_category().message(err); }

inline std::string hex(std::uint32_t value) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%X", static_cast<unsigned>(value));
  return buf;
}

inline std::int64_t realtime_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return std::int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
}

// Refuses frames no controller could put on the wire, so a bug above the bus layer shows up as an
// error at the call site instead of as a silently truncated identifier on the bus.
inline Result<void> check_sendable(const CanFrame& frame, const std::string& uri) {
  if (frame.len > CanFrame::kMaxLen) {
    return make_error(uri + ": frame length " + std::to_string(frame.len) + " exceeds 8");
  }
  // Error frames carry SocketCAN error class bits (29 bits wide) instead of an identifier.
  const bool wide = frame.extended || frame.error;
  if (frame.id > (wide ? 0x1FFF'FFFFu : 0x7FFu)) {
    return make_error(uri + ": identifier " + hex(frame.id) + " does not fit " + (wide ? "29" : "11") + " bits");
  }
  return {};
}

}  // namespace lb::can::detail
