#pragma once
// CiA 420-2 puller on DDS: rt/<line>/<device>/status (PullerStatus), setpoint (PullerSetpoint),
// setpoint_result, and the command service (motor_stop, motor_start, clamp_close, clamp_open,
// f1..f3 stop/start). See docs/devices/puller-corrugator.md.

#include "gateways/drive_gateway.hpp"
#include "gateways/puller_codec.hpp"
#include "msgs/pullerPubSubTypes.h"

namespace lb::gateways {

struct PullerDds {
  using Codec = PullerCodec;
  using StatusTopic = linebridge_msgs::msg::PullerStatusPubSubType;
  using SetpointTopic = linebridge_msgs::msg::PullerSetpointPubSubType;
};

extern template class DriveGateway<PullerDds>;
using PullerGateway = DriveGateway<PullerDds>;

}  // namespace lb::gateways
