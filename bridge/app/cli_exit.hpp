#pragma once
// linebridge-cli's exit codes: a script must tell "the bridge said no" from "nobody answered".

namespace lb::app {

inline constexpr int kExitOk = 0;
inline constexpr int kExitRefused = 1;   // the bridge answered and refused (the reason is printed)
inline constexpr int kExitUsage = 2;     // bad arguments or configuration; nothing was sent
inline constexpr int kExitNoAnswer = 3;  // no bridge, no answer in time, or the request could not be sent

}  // namespace lb::app
