#pragma once
// A device's PDOs as its boot compares them with the device: the profile's defaults with the
// line's overrides, and what the profile lets a master write of each.

#include <vector>

#include "canopen/pdo_parameters.hpp"
#include "profiles/line_config.hpp"

namespace lb::gateways {

std::vector<canopen::PdoSpec> pdo_specs(const profiles::Profile& profile, const profiles::DeviceConfig& device);

// A PDO as the boot left it, applied to the line's view of it (what the gateway decodes by).
profiles::DevicePdo in_use(const profiles::DevicePdo& configured, const canopen::PdoParameters& actual);

}  // namespace lb::gateways
