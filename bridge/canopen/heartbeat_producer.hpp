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
  // Loop thread: a standby that takes the bus over continues the master's heartbeat: operational
  // at once, no boot-up (the master did not boot, it changed hands).
  void resume();

 private:
  BusLoop& loop_;
  std::uint8_t node_id_;
  std::chrono::milliseconds period_;
  BusLoop::TimerId timer_;
};

}  // namespace lb::canopen
