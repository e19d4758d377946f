#pragma once
// linebridge-cli's exit codes: a script must tell "the bridge said no" from "nobody answered".
// 0 and 2 are every executable's (arguments.hpp).

#include <array>

#include "app/arguments.hpp"

namespace lb::app {

inline constexpr int kExitRefused = 1;   // the bridge answered and refused (the reason is printed)
inline constexpr int kExitNoAnswer = 3;  // no bridge, no answer in time, or the request could not be sent
// The bridge restarted after the request was first sent and refused to run it again: it may or
// may not have run before the restart (a script must look at the device before asking again).
inline constexpr int kExitBridgeRestarted = 4;

// Every code linebridge-cli leaves with, as its --help lists them.
inline constexpr std::array kCliExitCodes{
    ExitCode{kExitOk, "done"},
    ExitCode{kExitRefused, "the bridge answered and refused (the reason is printed), or a failure"},
    ExitCode{kExitUsage, "bad arguments or configuration"},
    ExitCode{kExitNoAnswer, "no answer: no bridge, no answer in time, or the request could not be sent"},
    ExitCode{kExitBridgeRestarted, "the bridge restarted after the request was first sent and did not run it again "
                                   "(it may or may not have run before the restart)"},
};

}  // namespace lb::app
