#include "sim/device_simulator.hpp"

#include <stdexcept>

#include "profiles/device_types.hpp"
#include "sim/drive_simulator.hpp"
#include "sim/feeder_simulator.hpp"
#include "sim/saw_simulator.hpp"

namespace lb::sim {

std::unique_ptr<DeviceSimulator> make_simulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device) {
  const auto& profile = *device.resolved_profile;
  const auto* type = profiles::find_device_type(profile.device);
  if (type == nullptr) {
    throw std::runtime_error(device.name + ": no simulator for device type '" + profile.device + "' (" + profile.key() +
                             ")");
  }
  switch (type->behaviour) {
    case profiles::Behaviour::drive: return std::make_unique<DriveSimulator>(loop, device, profile);
    case profiles::Behaviour::saw: return std::make_unique<SawSimulator>(loop, device, profile);
    case profiles::Behaviour::feeder: return std::make_unique<FeederSimulator>(loop, device, profile);
  }
  throw std::logic_error("unknown behaviour");
}

}  // namespace lb::sim
