#include "app/arguments.hpp"

#include <fastrtps/config.h>

#include <cmath>

#include "app/version.hpp"

namespace lb::app {
namespace {

constexpr double kYearSeconds = 365.0 * 24 * 3600;

}  // namespace

std::string version_text(std::string_view program) {
  return std::string(program) + " " + std::string(kVersion) + " (Fast DDS " + FASTRTPS_VERSION_STR + ")";
}

std::string exit_codes_text(std::span<const ExitCode> codes) {
  std::string out = "Exit codes:";
  for (const auto& c : codes)
    out += (out.back() == ':' ? " " : "; ") + std::to_string(c.code) + " " + std::string(c.meaning);
  return out + ".";
}

void add_conventions(CLI::App& cli, std::string_view program, std::span<const ExitCode> codes) {
  cli.set_version_flag("--version", version_text(program));
  cli.footer(exit_codes_text(codes));
}

int parse(CLI::App& cli, int argc, char** argv) {
  try {
    cli.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints help, the version or the error; its own codes (104, 105, 109, ...) would mean
    // something else to a service manager, so every argument error is a usage error.
    return cli.exit(e) == 0 ? kExitOk : kExitUsage;
  }
  return -1;
}

CLI::Option* add_config_option(CLI::App& cli, std::string& path) {
  return cli
      .add_option("-c,--config", path,
                  std::string("line configuration (YAML); default: the file ") + kConfigEnv +
                      " names, else the built-in demo line")
      ->envname(kConfigEnv)
      ->check(non_empty_path());
}

const CLI::Validator& duration_seconds() {
  static const CLI::Validator v(
      [](std::string& text) -> std::string {
        double d = 0;
        if (!CLI::detail::lexical_cast(text, d) || !std::isfinite(d) || d < 0 || d > kYearSeconds) {
          return "a duration is 0 (no limit) up to 31536000 seconds, not '" + text + "'";
        }
        return {};
      },
      "SECONDS 0..31536000");
  return v;
}

CLI::Validator positive_at_most(double max) {
  return CLI::Validator(
      [max](std::string& text) -> std::string {
        double d = 0;
        if (!CLI::detail::lexical_cast(text, d) || !std::isfinite(d) || d <= 0 || d > max) {
          return "expected a number greater than 0 and at most " + CLI::detail::to_string(max) + ", not '" + text + "'";
        }
        return {};
      },
      "NUMBER > 0");
}

const CLI::Validator& non_empty_path() {
  static const CLI::Validator v(
      [](std::string& text) -> std::string { return text.empty() ? "the path is empty" : std::string{}; }, "FILE");
  return v;
}

const CLI::Validator& log_level() {
  static const CLI::Validator v = CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"});
  return v;
}

std::chrono::milliseconds duration_ms(double seconds) {
  return std::chrono::milliseconds(static_cast<long long>(std::llround(seconds * 1000)));
}

}  // namespace lb::app
