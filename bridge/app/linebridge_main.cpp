// linebridge: the gateway process. Serves the buses and devices of one line configuration on DDS.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "app/arguments.hpp"
#include "app/async_log.hpp"
#include "app/dds_options.hpp"
#include "app/line_bridge.hpp"
#include "app/line_check.hpp"
#include "app/line_config_source.hpp"
#include "app/run_until_signal.hpp"
#include "app/service_notifier.hpp"
#include "dds/fastdds_log.hpp"

int main(int argc, char** argv) {
  namespace app = lb::app;
  CLI::App cli{"linebridge: CANopen extrusion-line devices on DDS"};
  app::add_conventions(cli, "linebridge");
  std::string config_path;
  std::string check_path;
  double duration_s = 0;
  std::string log_level = "info";
  cli.add_option("-c,--config", config_path, "line configuration (YAML); default: the built-in demo line")
      ->check(app::non_empty_path());
  cli.add_option("--check", check_path,
                 "check a line configuration (and its profile, DDS profile and security files) as start-up would, "
                 "print its buses, devices and DDS topics, and exit (0 valid, 2 not); touches neither CAN nor DDS")
      ->check(app::non_empty_path());
  cli.add_option("-d,--duration", duration_s, "stop after this many seconds (default 0: run until SIGINT/SIGTERM)")
      ->check(app::duration_seconds());
  cli.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")
      ->check(app::log_level())
      ->capture_default_str();
  if (const int code = app::parse(cli, argc, argv); code >= 0) return code;
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%H:%M:%S.%e [bridge] %^%l%$ %v");

  const auto registry = lb::profiles::ProfileRegistry::builtin();
  if (!check_path.empty()) {
    spdlog::set_level(spdlog::level::warn);  // the summary says it all; the gateways' start-up lines would not
    return app::check_line(check_path, registry, stdout, stderr);
  }

  // From here on no bus loop waits for the log.
  const app::AsyncLog async_log("%H:%M:%S.%e [bridge] %^%l%$ %v");
  app::block_stop_signals();
  auto config = app::load_config(config_path, registry);
  if (!config) {
    spdlog::error("{}", config.error().message);
    return app::kExitUsage;
  }
  for (const auto& w : config->warnings) spdlog::warn("{}", w);
  // Fast DDS's warnings (a reader refusing samples among them) and errors in this log, rate-limited.
  const lb::ddsl::FastDdsLogRoute fastdds_log;
  // DDS first: a secured participant that cannot prove security is in force is a configuration
  // error (exit 2), like a bad security file or DDS profile; nothing runs unsecured by mistake.
  const auto dds_options = app::bridge_participant_options(*config);
  auto dds = lb::ddsl::Participant::create_checked(dds_options);
  if (!dds) {
    spdlog::error("{}", dds.error().message);
    return dds.error().configuration ? app::kExitUsage : app::kExitFailure;
  }
  if (dds_options.security) {
    spdlog::info("{}", app::security_summary(dds_options));
    for (const auto& w : lb::ddsl::security_warnings(*dds_options.security)) spdlog::warn("DDS security: {}", w);
  }
  auto bridge = app::LineBridge::create(*config, std::move(*dds));
  if (!bridge) {
    spdlog::error("start-up failed: {}", bridge.error().message);
    return app::kExitFailure;
  }
  for (const auto& note : (*bridge)->dds().site_notes()) spdlog::warn("DDS profiles: {}", note);
  (*bridge)->start();
  spdlog::info("line {}: {} bus(es), {} device(s), DDS domain {}{}{}{}", config->line, config->buses.size(),
               config->devices.size(), config->dds.domain, config->dds.localhost_only ? " (localhost only)" : "",
               config->dds.discovery_servers.empty() ? "" : ", through discovery servers",
               config->dds.security ? ", secured" : "");
  app::ServiceNotifier notifier((*bridge)->watched_loops());
  if (notifier.watchdog().count() > 0) {
    spdlog::info("systemd watchdog: every bus loop must show progress within {} ms", notifier.watchdog().count() / 1000);
  }
  const int sig = app::run_until_signal(app::duration_ms(duration_s));
  notifier.stopping();
  if (const auto failure = (*bridge)->failure()) {
    // Exit non-zero so the service manager restarts the bridge rather than keep a line without its loop.
    spdlog::critical("stopping: {}", *failure);
    (*bridge)->stop();
    return app::kExitLoopFailed;
  }
  spdlog::info("stopping ({})", sig != 0 ? "signal" : "duration elapsed");
  (*bridge)->stop();
  return app::kExitOk;
}
