#pragma once
// Which run of a line's bridge serves it, as the bridge's diagnostics announce it (transient-local:
// the current run's sample arrives as soon as it is matched). A service client given this names
// that run in its requests, so a repeat that reaches a restarted bridge is refused, not run twice
// (dds/incarnation.hpp, dds/service.hpp).

#include <string>
#include <utility>

#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

inline ddsl::RunAnnouncements bridge_runs(std::string line) {
  return [line = std::move(line)](ddsl::Participant& dds, std::function<void(ddsl::Incarnation)> heard) {
    return dds.subscribe_scoped<linebridge_msgs::msg::DiagnosticsPubSubType>(
        ddsl::topic_name(line, ddsl::kBridgeNamespace, "diagnostics"), ddsl::QosKind::state,
        [heard = std::move(heard)](const linebridge_msgs::msg::Diagnostics& d, const ddsl::fdds::SampleInfo&) {
          heard(d.bridge_incarnation());
        });
  };
}

}  // namespace lb::gateways
