#pragma once
// Argument conventions shared by every executable: exit codes, --version, and the validators of
// options whose bad values CLI11 would otherwise take (a negative or NaN duration, an unknown log
// level, an empty configuration path).

#include <CLI/CLI.hpp>

#include <array>
#include <chrono>
#include <span>
#include <string>
#include <string_view>

namespace lb::app {

// Exit codes of every executable (README "Exit codes").
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;     // a failure: start-up, a part of the bridge at run time (CLI: cli_exit.hpp)
inline constexpr int kExitUsage = 2;       // bad arguments or configuration: retrying cannot help
inline constexpr int kExitLoopFailed = 3;  // linebridge: a bus loop failed while running (restart it)

// An exit code and what it means, as --help lists it.
struct ExitCode {
  int code;
  std::string_view meaning;
};

// Each program's own: what its code paths return, in its words (docs/command-line.md "Exit codes").
// linebridge-cli's are in cli_exit.hpp: it alone sends requests, so it alone has refusals.
inline constexpr ExitCode kExitDone{kExitOk, "done"};
inline constexpr ExitCode kExitBadUsage{kExitUsage, "bad arguments or configuration"};
inline constexpr std::array kBridgeExitCodes{
    ExitCode{kExitOk, "normal stop (SIGINT, SIGTERM, --duration), or --check found the file valid"},
    ExitCode{kExitFailure, "start-up failure (a bus, the channel or the DDS participant cannot be opened), or "
                           "--part dds lost its channel to the bus process"},
    ExitCode{kExitUsage, "bad arguments or configuration, or --check found the file not valid"},
    ExitCode{kExitLoopFailed, "a bus loop failed while running (restart it)"},
};
inline constexpr std::array kSimExitCodes{
    kExitDone,
    ExitCode{kExitFailure, "a bus cannot be opened or a device cannot be played"},
    kExitBadUsage,
};
inline constexpr std::array kSecurityExitCodes{
    ExitCode{kExitOk, "the check passed, the document was printed"},
    ExitCode{kExitUsage, "bad arguments or configuration, a problem in a security file"},
};

// "Exit codes: 0 done; 1 ...; 2 ...": the --help footer.
std::string exit_codes_text(std::span<const ExitCode> codes);

// "linebridge 0.1.0 (Fast DDS 2.9.1)".
std::string version_text(std::string_view program);

// Adds --version, lists `codes` under --help and makes CLI11's own failures follow the
// conventions above.
void add_conventions(CLI::App& cli, std::string_view program, std::span<const ExitCode> codes);

// Parses; returns the exit code to leave with (0 after --help/--version, kExitUsage for any
// argument error, which CLI11 prints) or -1 to go on.
int parse(CLI::App& cli, int argc, char** argv);

// -c,--config FILE, or the file LINEBRIDGE_CONFIG names (the option wins); neither: the built-in
// demo line. The same for linebridge, linebridge-sim, linebridge-cli and linebridge-security.
inline constexpr const char* kConfigEnv = "LINEBRIDGE_CONFIG";
CLI::Option* add_config_option(CLI::App& cli, std::string& path);

// Validators.
// A duration in seconds: finite, 0 (no limit) up to a year. Refuses -5, nan, inf, 1e30.
const CLI::Validator& duration_seconds();
// A finite number greater than 0 and at most `max` (rates, timeouts).
CLI::Validator positive_at_most(double max);
// A path that is not empty ("" would otherwise mean "the built-in demo line").
const CLI::Validator& non_empty_path();
// trace, debug, info, warn, error, critical, off.
const CLI::Validator& log_level();

// --duration's value (validated) as the chrono duration run_until_signal takes; 0 = no limit.
std::chrono::milliseconds duration_ms(double seconds);

}  // namespace lb::app
