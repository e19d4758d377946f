#include "sim/device_simulator.hpp"

#include <stdexcept>

#include "sim/saw_simulator.hpp"

namespace lb::sim {

std::unique_ptr<DeviceSimulator> make_simulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device) {
  const auto& profile = *device.resolved_profile;
  if (profile.device == "saw") return std::make_unique<SawSimulator>(loop, device, profile);
  throw std::runtime_error(device.name + ": no simulator for device type '" + profile.device + "' (" + profile.key() + ")");
}

}  // namespace lb::sim
