#include "sim/device_simulator.hpp"

#include <stdexcept>

#include "sim/drive_simulator.hpp"
#include "sim/feeder_simulator.hpp"
#include "sim/saw_simulator.hpp"

namespace lb::sim {

std::unique_ptr<DeviceSimulator> make_simulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device) {
  const auto& profile = *device.resolved_profile;
  if (profile.device == "saw") return std::make_unique<SawSimulator>(loop, device, profile);
  if (profile.device == "feeder") return std::make_unique<FeederSimulator>(loop, device, profile);
  if (profile.device == "puller" || profile.device == "corrugator") {
    return std::make_unique<DriveSimulator>(loop, device, profile);
  }
  throw std::runtime_error(device.name + ": no simulator for device type '" + profile.device + "' (" + profile.key() + ")");
}

}  // namespace lb::sim
