#pragma once
// The object dictionary a simulated device serves by SDO: every object of its profile, plus the
// CiA 301 communication objects a master reads or writes (device type, identity, names, heartbeat
// time, PDO communication and mapping parameters).

#include <string>

#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"

namespace lb::sim {

// Throws std::runtime_error (start-up) on a profile the dictionary cannot represent.
canopen::ObjectDictionary make_device_dictionary(const profiles::DeviceConfig& device, const profiles::Profile& profile);

// The long, segmented-transfer-sized device name the simulators report in 1008h.
std::string simulated_device_name(const profiles::DeviceConfig& device, const profiles::Profile& profile);

}  // namespace lb::sim
