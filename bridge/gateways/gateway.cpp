#include "gateways/gateway.hpp"

#include <stdexcept>

#include "gateways/corrugator_gateway.hpp"
#include "gateways/puller_gateway.hpp"
#include "gateways/feeder_gateway.hpp"
#include "gateways/saw_gateway.hpp"

namespace lb::gateways {

std::unique_ptr<Gateway> make_gateway(DeviceContext context) {
  if (context.profile.device == "saw") return std::make_unique<SawGateway>(context);
  if (context.profile.device == "feeder") return std::make_unique<FeederGateway>(context);
  if (context.profile.device == "puller") return std::make_unique<PullerGateway>(context);
  if (context.profile.device == "corrugator") return std::make_unique<CorrugatorGateway>(context);
  throw std::runtime_error(context.device.name + ": no gateway for device type '" + context.profile.device + "' (" +
                           context.profile.key() + ")");
}

}  // namespace lb::gateways
