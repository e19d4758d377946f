#pragma once
// Human-readable one-line renderings of puller and corrugator status samples, for linebridge-cli.

#include <string>

#include "msgs/corrugator.h"
#include "msgs/puller.h"

namespace lb::app {

std::string to_text(const linebridge_msgs::msg::PullerStatus& s);
std::string to_text(const linebridge_msgs::msg::CorrugatorStatus& s);
std::string to_text(linebridge_msgs::msg::PullerSpeedSetMode m);

}  // namespace lb::app
