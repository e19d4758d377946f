#pragma once
// Human-readable one-line renderings of saw samples, for linebridge-cli.

#include <string>

#include "app/common_text.hpp"
#include "msgs/saw.h"

namespace lb::app {

std::string to_text(const linebridge_msgs::msg::SawStatus& s);
std::string to_text(const linebridge_msgs::msg::SawCut& c);
std::string to_text(linebridge_msgs::msg::SawCountMode m);

}  // namespace lb::app
