#pragma once
// A client's wait for a device's boot to have passed, as the bridge's diagnostics report it: the
// bridge refuses a set value that enables a device it has not configured yet, and "online" comes
// before the boot's end (seen: the demo's set value 14 ms before the saw's boot passed).

#include <chrono>
#include <string>

#include "base/result.hpp"
#include "dds/participant.hpp"
#include "msgs/common.h"

namespace lb::app {

// Nothing is under way any more: the boot passed (started, or configured and kept as an
// operator left it), or it settled where the bridge's own answer says why (boot failed, running
// unmanaged, held by the line, monitored). Not while it is unknown, booting, resetting or lost.
bool boot_settled(const linebridge_msgs::msg::NodeDiagnostics& node);

// Waits until rt/<line>/bridge/diagnostics says boot_settled for `device`; the error says what
// the diagnostics said last (or that none came).
Result<void> wait_for_boot(ddsl::Participant& dds, const std::string& line, const std::string& device,
                           std::chrono::steady_clock::duration timeout);

}  // namespace lb::app
