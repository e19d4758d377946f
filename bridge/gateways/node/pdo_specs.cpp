#include "gateways/node/pdo_specs.hpp"

#include <stdexcept>

namespace lb::gateways {

std::vector<canopen::PdoSpec> pdo_specs(const profiles::Profile& profile, const profiles::DeviceConfig& device) {
  std::vector<canopen::PdoSpec> specs;
  for (const auto& pdo : device.pdos) {
    const profiles::PdoDef* def = profile.pdo(pdo.name);
    if (def == nullptr) throw std::logic_error(device.name + ": " + pdo.name + " is not a PDO of " + profile.key());
    canopen::PdoSpec s;
    s.name = pdo.name;
    s.transmit = pdo.direction == profiles::PdoDirection::tx;
    s.communication_index = def->communication_index();
    s.mapping_index = def->mapping_index();
    s.wanted.cob_id = pdo.cob_id_entry();
    s.wanted.transmission_type = pdo.transmission_type;
    s.wanted.inhibit_time = static_cast<std::uint16_t>(pdo.inhibit.count() / 100);
    s.wanted.event_timer = static_cast<std::uint16_t>(pdo.event_timer.count());
    s.wanted.mapping = pdo.mapping;
    s.validity_given = pdo.validity_given;
    s.optional = !def->mandatory;
    s.rules = def->rules;
    specs.push_back(std::move(s));
  }
  return specs;
}

profiles::DevicePdo in_use(const profiles::DevicePdo& configured, const canopen::PdoParameters& actual) {
  profiles::DevicePdo p = configured;
  p.enabled = actual.valid();
  p.transmission_type = actual.transmission_type;
  p.mapping = actual.mapping;
  // A TPDO's timing is the device's; an RPDO's is how the bridge sends it, which stays the line's.
  if (configured.direction == profiles::PdoDirection::tx) {
    p.inhibit = std::chrono::microseconds(100 * actual.inhibit_time);
    p.event_timer = std::chrono::milliseconds(actual.event_timer);
  }
  return p;
}

}  // namespace lb::gateways
