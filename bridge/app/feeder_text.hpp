#pragma once
// Human-readable renderings of feeder box samples, for linebridge-cli: codes and functions by
// name, a line per feeder.

#include <string>

#include "msgs/feeder.h"

namespace lb::app {

std::string to_text(const linebridge_msgs::msg::FeederStatus& s);
std::string to_text(const linebridge_msgs::msg::FeederUnwinding& u);
std::string to_text(const linebridge_msgs::msg::FeederError& e);
std::string to_text(const linebridge_msgs::msg::FeederCode& c);

}  // namespace lb::app
