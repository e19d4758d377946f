#pragma once
// Human-readable one-line renderings of saw samples, for linebridge-cli.

#include <string>

#include "msgs/saw.h"

namespace lb::app {

std::string to_text(const linebridge_msgs::msg::SawStatus& s);
std::string to_text(const linebridge_msgs::msg::SawCut& c);
std::string to_text(linebridge_msgs::msg::NmtState s);
std::string clock_text(const linebridge_msgs::msg::Time& t);  // local HH:MM:SS.mmm

}  // namespace lb::app
