#pragma once
// CANopen NMT state to its DDS enumeration.

#include "canopen/nmt.hpp"
#include "msgs/common.h"

namespace lb::gateways {

constexpr linebridge_msgs::msg::NmtState to_msg(canopen::NmtState s) {
  namespace msg = linebridge_msgs::msg;
  switch (s) {
    case canopen::NmtState::boot_up: return msg::NMT_BOOT_UP;
    case canopen::NmtState::stopped: return msg::NMT_STOPPED;
    case canopen::NmtState::operational: return msg::NMT_OPERATIONAL;
    case canopen::NmtState::pre_operational: return msg::NMT_PRE_OPERATIONAL;
    case canopen::NmtState::unknown: break;
  }
  return msg::NMT_UNKNOWN;
}

}  // namespace lb::gateways
