#pragma once
// The bridge's own heartbeat in the master role (CiA 301 1017h): devices that consume it can tell
// their master is alive.

#include <chrono>
#include <cstdint>

#include "canopen/bus_loop.hpp"

namespace lb::canopen {

class HeartbeatProducer {
 public:
  HeartbeatProducer(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds period);
  void start();  // loop thread or before the loop starts

 private:
  BusLoop& loop_;
  std::uint8_t node_id_;
  std::chrono::milliseconds period_;
  BusLoop::TimerId timer_;
};

}  // namespace lb::canopen
