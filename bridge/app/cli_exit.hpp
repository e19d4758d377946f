#pragma once
// linebridge-cli's exit codes: a script must tell "the bridge said no" from "nobody answered".
// 0 and 2 are every executable's (arguments.hpp).

#include "app/arguments.hpp"

namespace lb::app {

inline constexpr int kExitRefused = 1;   // the bridge answered and refused (the reason is printed)
inline constexpr int kExitNoAnswer = 3;  // no bridge, no answer in time, or the request could not be sent
// The bridge restarted after the request was first sent and refused to run it again: it may or
// may not have run before the restart (a script must look at the device before asking again).
inline constexpr int kExitBridgeRestarted = 4;

}  // namespace lb::app
