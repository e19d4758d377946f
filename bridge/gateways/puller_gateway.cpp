#include "gateways/puller_gateway.hpp"

namespace lb::gateways {

template class DriveGateway<PullerDds>;

}  // namespace lb::gateways
