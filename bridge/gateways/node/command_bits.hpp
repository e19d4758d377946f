#pragma once
// A device's momentary commands as its profile names them: the control word bit each presses and
// whether the profile marks it `stopping` (a stop is never refused while the device is heard).

#include <string>
#include <vector>

#include "profiles/profile.hpp"

namespace lb::gateways {

struct CommandBit {
  std::string name;  // the profile's bit name, e.g. "manual_cut"
  unsigned bit;
  bool stopping = false;  // marked `stopping` in the profile
};

// Resolves the names in the profile's bit set; names the profile lacks (older versions) are left
// out.
std::vector<CommandBit> resolve_commands(const profiles::BitSet& control_word, const std::vector<std::string>& names);

}  // namespace lb::gateways
