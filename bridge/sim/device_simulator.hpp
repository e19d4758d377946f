#pragma once
// A simulated device: the device side of one profile on a bus loop. linebridge-sim owns one per
// device of the line configuration it plays.

#include <memory>

#include "canopen/bus_loop.hpp"
#include "profiles/line_config.hpp"

namespace lb::sim {

class DeviceSimulator {
 public:
  virtual ~DeviceSimulator() = default;
  virtual void start() = 0;  // boot-up; loop thread or before the loop starts
};

// The simulator for the device type the profile names; throws std::runtime_error (start-up) for a
// device type none simulates.
std::unique_ptr<DeviceSimulator> make_simulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device);

}  // namespace lb::sim
