#pragma once
// A simulated device's heartbeat consumer (CiA 301 1016h), so that a device that depends on its
// master's heartbeat behaves as a real one when that heartbeat pauses (a takeover of the bus):
// one entry, sub 1 = node-ID in bits 16..23 and the consumer time in ms in bits 0..15 (0: unused),
// written over SDO like any device's. The entry becomes active with the first heartbeat of that
// node after it was written; a heartbeat then missing for the consumer time is a heartbeat event:
// on_event (the device raises EMCY 8130h and, by 1029h sub 1's default 0, leaves operational for
// pre-operational). The next heartbeat ends it (on_recovered) and makes the entry active again.
// Reset communication and reset node restore the power-on value 0.

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>

#include "canopen/bus_loop.hpp"
#include "canopen/sdo_server.hpp"

namespace lb::sim {

class HeartbeatConsumer {
 public:
  // Before the loop starts: adds 1016h to the dictionary.
  HeartbeatConsumer(canopen::BusLoop& loop, canopen::ObjectDictionary& od, std::function<void()> on_event,
                    std::function<void()> on_recovered);
  HeartbeatConsumer(const HeartbeatConsumer&) = delete;
  HeartbeatConsumer& operator=(const HeartbeatConsumer&) = delete;

  void reset();  // loop thread: the power-on value (no entry)

 private:
  void heartbeat(const can::CanFrame& frame);
  void expired();

  canopen::BusLoop& loop_;
  std::function<void()> on_event_;
  std::function<void()> on_recovered_;
  canopen::BusLoop::TimerId timer_;
  std::uint32_t entry_ = 0;  // 1016h sub 1
  bool active_ = false;      // a heartbeat came since the entry was written
  bool in_event_ = false;    // the heartbeat is missing now
  std::array<bool, 128> listening_{};
};

}  // namespace lb::sim
