// The composition point of the device gateways: the registry entry's behaviour picks the
// component; a drive's DDS types come from the word binding its entry names.
#include <stdexcept>

#include "gateways/adapters/drive_gateway.hpp"
#include "gateways/adapters/feeder_gateway.hpp"
#include "gateways/adapters/gateway.hpp"
#include "gateways/adapters/saw_gateway.hpp"
#include "gateways/codecs/drive_binding.hpp"
#include "profiles/device_types.hpp"

namespace lb::gateways {

namespace {

std::unique_ptr<Gateway> make_drive_gateway(const profiles::DeviceType& type, const DeviceContext& context) {
  std::unique_ptr<Gateway> gateway;
  if (!visit_drive(type.idl, [&]<class Binding>() { gateway = std::make_unique<DriveGateway<Binding>>(context); })) {
    throw std::runtime_error(context.device.name + ": device type '" + std::string(type.name) + "' names IDL '" +
                             std::string(type.idl) + "', which declares no drive-shaped word binding");
  }
  return gateway;
}

}  // namespace

std::unique_ptr<Gateway> make_gateway(DeviceContext context) {
  const auto* type = profiles::find_device_type(context.profile.device);
  if (type == nullptr) {
    throw std::runtime_error(context.device.name + ": no gateway for device type '" + context.profile.device + "' (" +
                             context.profile.key() + ")");
  }
  switch (type->behaviour) {
    case profiles::Behaviour::drive: return make_drive_gateway(*type, context);
    case profiles::Behaviour::saw: return std::make_unique<SawGateway>(context);
    case profiles::Behaviour::feeder: return std::make_unique<FeederGateway>(context);
  }
  throw std::logic_error("unknown behaviour");
}

}  // namespace lb::gateways
