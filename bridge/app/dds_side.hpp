#pragma once
// The DDS process of a line (docs/bus-isolation.md): the participant, DDS Security and the site's
// QoS; every topic and service endpoint the bus process declares over the channel, created as it
// declares them; samples relayed both ways. It holds nothing the line needs to keep running, so it
// may die (a Fast DDS abort under a forged-discovery flood) and be restarted at any moment: the
// bus process sends a fresh one everything again (declarations, then the newest state).

#include <chrono>
#include <string>

#include "dds/participant.hpp"
#include "profiles/line_config.hpp"

namespace lb::app {

// Returns the exit code: kExitOk on a stop signal or when `duration` elapsed, kExitUsage for a
// configuration the DDS side refuses (security), kExitFailure when the channel to the bus process
// fails (its supervisor starts a new DDS process). `observability`: where its status page and
// metrics are served (app/observability/); a server that cannot listen is an error in the log, and
// the DDS side runs on without it.
int run_dds_side(const ddsl::ParticipantOptions& options, const std::string& line,
                 const profiles::ObservabilityConfig& observability, const std::string& channel_path,
                 std::chrono::milliseconds duration);

}  // namespace lb::app
