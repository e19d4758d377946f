#pragma once
// linebridge --check CONFIG: everything start-up would refuse in a line file, its profile files
// (profiles_dir), its DDS profiles file and its security files, plus warnings an integrator should
// read, and a summary of the buses, devices and every DDS topic the bridge will create. Touches
// neither CAN nor DDS: the gateways are built on stand-in buses and a planning participant.

#include <cstdio>
#include <string>

#include "profiles/profile_registry.hpp"

namespace lb::app {

// Prints the summary and warnings to `out`, errors to `err`; returns the exit code (0 valid,
// 2 invalid).
int check_line(const std::string& path, const profiles::ProfileRegistry& registry, std::FILE* out, std::FILE* err);

// linebridge --check CONFIG --peer PEER: each file as above, then the pair as two bridges of one
// line, one the other's standby (docs/redundancy.md): the same line, DDS domain, buses and devices
// (names, node-IDs, profiles), on each bus the same master_node_id, SYNC period and master heartbeat
// period, both in the standby role, and different flying-master priorities (the negotiation tells
// them apart by priority: they share the master node-ID). Returns 0 or 2.
int check_pair(const std::string& path, const std::string& peer, const profiles::ProfileRegistry& registry,
               std::FILE* out, std::FILE* err);

}  // namespace lb::app
