#pragma once
// linebridge-cli eds FILE: reads a device vendor's EDS or DCF (CiA 306), checks it against the
// profile a device of the line uses (device type, every profile object's presence, data type,
// access and PDO mappability) and prints the line-file entries it implies: the identity values
// (1000h, 1018h) and the PDO overrides where the device's own defaults differ from the profile's.

#include <string>

#include "profiles/line_config.hpp"

namespace lb::app {

struct EdsOptions {
  std::string file;
  std::string device;           // a device of the line: its profile, node-ID and PDOs
  std::string profile;          // or a profile id ...
  std::string profile_version;  // ... and version
  int node_id = 0;              // for $NODEID; 0: a DCF's NodeID, else the device's
};

// Exit code: 0 the file fits the profile, 1 it does not (each finding printed), 2 the file cannot
// be read or the arguments do not name a profile.
int run_eds(const profiles::LineConfig& line, const profiles::ProfileRegistry& registry, const EdsOptions& o);

}  // namespace lb::app
