#include "gateways/corrugator_gateway.hpp"

namespace lb::gateways {

template class DriveGateway<CorrugatorDds>;

}  // namespace lb::gateways
