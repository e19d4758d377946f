// linebridge: the gateway process. Serves the buses and devices of one line configuration on DDS.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "app/dds_options.hpp"
#include "app/line_bridge.hpp"
#include "app/line_config_source.hpp"
#include "app/run_until_signal.hpp"

int main(int argc, char** argv) {
  CLI::App cli{"linebridge: CANopen extrusion-line devices on DDS"};
  std::string config_path;
  double duration_s = 0;
  std::string log_level = "info";
  cli.add_option("-c,--config", config_path, "line configuration (YAML); default: the built-in demo line");
  cli.add_option("-d,--duration", duration_s, "stop after this many seconds (default: run until Ctrl-C)");
  cli.add_option("--log-level", log_level, "trace, debug, info, warn, error")->capture_default_str();
  CLI11_PARSE(cli, argc, argv);
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%H:%M:%S.%e [bridge] %^%l%$ %v");

  lb::app::block_stop_signals();
  const auto registry = lb::profiles::ProfileRegistry::builtin();
  auto config = lb::app::load_config(config_path, registry);
  if (!config) {
    spdlog::error("{}", config.error().message);
    return 2;
  }
  // DDS first: a secured participant that cannot prove security is in force is a configuration
  // error (exit 2), like a bad security file; nothing runs unsecured by mistake.
  const auto dds_options = lb::app::bridge_participant_options(*config);
  auto dds = lb::ddsl::Participant::create_checked(dds_options);
  if (!dds) {
    spdlog::error("{}", dds.error().message);
    return dds.error().configuration ? 2 : 1;
  }
  if (dds_options.security) spdlog::info("{}", lb::app::security_summary(dds_options));
  auto bridge = lb::app::LineBridge::create(*config, std::move(*dds));
  if (!bridge) {
    spdlog::error("start-up failed: {}", bridge.error().message);
    return 1;
  }
  (*bridge)->start();
  spdlog::info("line {}: {} bus(es), {} device(s), DDS domain {}{}{}", config->line, config->buses.size(),
               config->devices.size(), config->dds.domain, config->dds.localhost_only ? " (localhost only)" : "",
               config->dds.security ? ", secured" : "");
  const int sig = lb::app::run_until_signal(std::chrono::milliseconds(static_cast<long>(duration_s * 1000)));
  if (const auto failure = (*bridge)->failure()) {
    // Exit non-zero so the service manager restarts the bridge rather than keep a line without its loop.
    spdlog::critical("stopping: {}", *failure);
    (*bridge)->stop();
    return 3;
  }
  spdlog::info("stopping ({})", sig != 0 ? "signal" : "duration elapsed");
  (*bridge)->stop();
  return 0;
}
