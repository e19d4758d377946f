#pragma once
// Waiting on what a BusSpy shows, with a generous deadline, instead of sleeping a fixed window:
// a test waits for frames (by identifier, content or bus stamp), then asserts on them.
//
// A negative check ("no such frame came") needs a positive marker first: a frame of the same
// sender stamped after the moment from which nothing may come. The bus is ordered, so once the
// spy holds that later frame it also holds every frame sent before it.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <functional>

#include "can/can_frame.hpp"
#include "can/detail.hpp"
#include "support/bus_spy.hpp"
#include "support/eventually.hpp"

namespace lb::test {

// Now, on the clock the bus stamps frames with (CanFrame::timestamp_ns: CLOCK_REALTIME).
inline std::int64_t bus_now_ns() { return lb::can::detail::realtime_ns(); }

// A frame with this identifier that matches.
inline bool wait_frame(BusSpy& spy, std::uint32_t id, const std::function<bool(const lb::can::CanFrame&)>& match,
                       std::chrono::steady_clock::duration timeout = std::chrono::seconds(10)) {
  return eventually(timeout, [&] {
    for (const auto& f : spy.frames(id)) {
      if (match(f)) return true;
    }
    return false;
  });
}

// At least `count` frames with this identifier stamped after `after_ns` (bus_now_ns()): the bus
// went on past that moment, and the spy holds everything sent before it.
inline bool wait_frames_after(BusSpy& spy, std::uint32_t id, std::int64_t after_ns, std::size_t count = 1,
                              std::chrono::steady_clock::duration timeout = std::chrono::seconds(10)) {
  return eventually(timeout, [&] {
    std::size_t n = 0;
    for (const auto& f : spy.frames(id)) n += f.timestamp_ns > after_ns ? 1 : 0;
    return n >= count;
  });
}

}  // namespace lb::test
