#pragma once
// linebridge-cli's exit codes: a script must tell "the bridge said no" from "nobody answered".
// 0 and 2 are every executable's (arguments.hpp).

#include "app/arguments.hpp"

namespace lb::app {

inline constexpr int kExitRefused = 1;   // the bridge answered and refused (the reason is printed)
inline constexpr int kExitNoAnswer = 3;  // no bridge, no answer in time, or the request could not be sent

}  // namespace lb::app
