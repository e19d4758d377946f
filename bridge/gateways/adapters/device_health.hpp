#pragma once
// The part of every device status that comes from CANopen itself, not from the profile.

#include "canopen/remote_node.hpp"
#include "gateways/codecs/nmt_state_msg.hpp"
#include "msgs/common.h"

namespace lb::gateways {

inline void fill_health(const canopen::RemoteNode& node, linebridge_msgs::msg::DeviceHealth& health) {
  health.nmt_state(to_msg(node.state()));
  health.online(node.online());
  health.error_register(node.errors().error_register());
  health.active_errors(node.errors().codes());
  health.active_errors_known(node.errors().known());
  health.active_errors_note(node.errors().note());
}

}  // namespace lb::gateways
