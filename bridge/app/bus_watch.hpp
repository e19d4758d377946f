#pragma once
// linebridge-cli candump BUS: the raw frames of a bus the line's bridge serves, virtual buses
// included, in can-utils' log format (what `candump -l` writes, `canplayer` replays) with what
// each frame is in CiA 301 terms. The watcher joins the bus listen-only: it can send nothing.

#include <cstdint>
#include <string>

#include "can/can_frame.hpp"
#include "profiles/line_config.hpp"

namespace lb::app {

struct WatchOptions {
  double duration_s = 0;    // 0: until SIGINT/SIGTERM
  std::uint64_t count = 0;  // stop after this many frames; 0: no limit
  bool log_only = false;    // the bare log line, for a file canplayer replays
};

// "TPDO1 node 3", "SYNC", "heartbeat node 5: operational", "SDO request to node 3", ...
std::string describe_frame(const can::CanFrame& frame);

// Returns the exit code: 0 after the duration, the count or a signal; 2 for an unknown bus or a
// log: bus (a replay is a file: read it); 1 when the bus cannot be opened.
int watch_bus(const profiles::LineConfig& line, const std::string& bus, const WatchOptions& options);

}  // namespace lb::app
