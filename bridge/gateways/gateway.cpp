#include "gateways/gateway.hpp"

#include <stdexcept>

#include "gateways/saw_gateway.hpp"

namespace lb::gateways {

std::unique_ptr<Gateway> make_gateway(DeviceContext context) {
  if (context.profile.device == "saw") return std::make_unique<SawGateway>(context);
  throw std::runtime_error(context.device.name + ": no gateway for device type '" + context.profile.device + "' (" +
                           context.profile.key() + ")");
}

}  // namespace lb::gateways
