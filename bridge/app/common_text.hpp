#pragma once
// Human-readable renderings of the device-independent samples, for linebridge-cli.

#include <string>

#include "msgs/common.h"

namespace lb::app {

std::string to_text(const linebridge_msgs::msg::Emergency& e);
std::string to_text(const linebridge_msgs::msg::DeviceInfo& i);
std::string to_text(const linebridge_msgs::msg::Diagnostics& d);
std::string to_text(const linebridge_msgs::msg::BootError& e);

}  // namespace lb::app
