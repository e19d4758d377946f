#pragma once
// Receiving from a CAN bus in a test as an event loop would: every frame the bus delivers,
// waiting on its fd() between them, until `count` frames came or the deadline passed. A receive
// error ends it as a test failure (the frames so far are returned).

#include <gtest/gtest.h>
#include <poll.h>

#include <chrono>
#include <cstddef>
#include <vector>

#include "can/bus.hpp"

namespace lb::test {

inline std::vector<lb::can::CanFrame> drain(lb::can::Bus& bus, std::size_t count,
                                            std::chrono::milliseconds timeout = std::chrono::seconds(3)) {
  std::vector<lb::can::CanFrame> out;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (out.size() < count && std::chrono::steady_clock::now() < deadline) {
    auto r = bus.receive();
    if (!r) {
      ADD_FAILURE() << r.error().message;
      return out;
    }
    if (*r) {
      out.push_back(**r);
      continue;
    }
    pollfd p{bus.fd(), POLLIN, 0};
    ::poll(&p, 1, 50);
  }
  return out;
}

}  // namespace lb::test
