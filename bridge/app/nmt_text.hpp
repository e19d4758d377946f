#pragma once
// A CiA 301 NMT state in the words the CLI, the diagnostics text and the status page all print.
// Header-only: the status page's library (observability/) sits below lb_app, which links it.

#include <string_view>

#include "msgs/common.h"

namespace lb::app {

inline std::string_view nmt_text(linebridge_msgs::msg::NmtState s) {
  namespace msg = linebridge_msgs::msg;
  switch (s) {
    case msg::NMT_BOOT_UP: return "boot-up";
    case msg::NMT_STOPPED: return "stopped";
    case msg::NMT_OPERATIONAL: return "operational";
    case msg::NMT_PRE_OPERATIONAL: return "pre-operational";
    case msg::NMT_UNKNOWN: break;
  }
  return "unknown";
}

}  // namespace lb::app
