#pragma once
// Human-readable renderings of the device-independent samples, for linebridge-cli.

#include <string>
#include <vector>

#include "msgs/common.h"

namespace lb::app {

std::string to_text(const linebridge_msgs::msg::Emergency& e);
std::string to_text(const linebridge_msgs::msg::DeviceInfo& i);
std::string to_text(const linebridge_msgs::msg::Diagnostics& d);
std::string to_text(const linebridge_msgs::msg::BootError& e);
std::string to_text(linebridge_msgs::msg::NmtState s);
std::string clock_text(const linebridge_msgs::msg::Time& t);  // local HH:MM:SS.mmm

// The parts every status line shares: "operational online", " | EMCY active: ..." (and whether the
// list is known), " | other: name value unit, ...".
std::string state_text(const linebridge_msgs::msg::DeviceHealth& h);
std::string errors_text(const linebridge_msgs::msg::DeviceHealth& h);
std::string other_values_text(const std::vector<linebridge_msgs::msg::ProcessValue>& values);

}  // namespace lb::app
