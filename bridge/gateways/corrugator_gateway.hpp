#pragma once
// CiA 420-3 corrugator on DDS: rt/<line>/<device>/status (CorrugatorStatus), setpoint
// (CorrugatorSetpoint), setpoint_result, and the command service (drive_stop, drive_start, move_in,
// move_out, f1..f3 stop/start). See docs/devices/puller-corrugator.md.

#include "gateways/corrugator_codec.hpp"
#include "gateways/drive_gateway.hpp"
#include "msgs/corrugatorPubSubTypes.h"

namespace lb::gateways {

struct CorrugatorDds {
  using Codec = CorrugatorCodec;
  using StatusTopic = linebridge_msgs::msg::CorrugatorStatusPubSubType;
  using SetpointTopic = linebridge_msgs::msg::CorrugatorSetpointPubSubType;
};

extern template class DriveGateway<CorrugatorDds>;
using CorrugatorGateway = DriveGateway<CorrugatorDds>;

}  // namespace lb::gateways
