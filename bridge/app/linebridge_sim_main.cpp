// linebridge-sim: plays the devices of a line configuration on their buses, for demos and tests.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <memory>
#include <vector>

#include "app/arguments.hpp"
#include "app/line_config_source.hpp"
#include "app/run_until_signal.hpp"
#include "canopen/bus_loop.hpp"
#include "sim/device_simulator.hpp"
#include "sim/line_controller.hpp"

int main(int argc, char** argv) {
  CLI::App cli{"linebridge-sim: simulated CANopen devices of a line"};
  lb::app::add_conventions(cli, "linebridge-sim", lb::app::kSimExitCodes);
  std::string config_path;
  std::vector<std::string> only;
  double duration_s = 0;
  std::string log_level = "info";
  std::string role = "devices";
  lb::app::add_config_option(cli, config_path);
  cli.add_option("--role", role,
                 "devices: play the devices; controller: play the line controller (SYNC, NMT, RPDOs from "
                 "simulation.controller_values) for a bridge in the monitor role; both")
      ->check(CLI::IsMember({"devices", "controller", "both"}))
      ->capture_default_str();
  cli.add_option("--device", only, "simulate only these devices (default: all)");
  cli.add_option("-d,--duration", duration_s, "stop after this many seconds (default 0: run until SIGINT/SIGTERM)")
      ->check(lb::app::duration_seconds());
  cli.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")
      ->check(lb::app::log_level())
      ->capture_default_str();
  if (const int code = lb::app::parse(cli, argc, argv); code >= 0) return code;
  spdlog::set_level(spdlog::level::from_str(log_level));
  spdlog::set_pattern("%H:%M:%S.%e [sim] %^%l%$ %v");

  lb::app::block_stop_signals();
  const auto registry = lb::profiles::ProfileRegistry::builtin();
  auto config = lb::app::load_config(config_path, registry);
  if (!config) {
    spdlog::error("{}", config.error().message);
    return 2;
  }
  spdlog::info("playing {}", lb::app::config_source_text(config_path));
  for (const auto& name : only) {
    if (config->device(name) == nullptr) {
      spdlog::error("--device {}: no such device in line {}", name, config->line);
      return 2;
    }
  }

  std::vector<std::unique_ptr<lb::canopen::BusLoop>> loops;
  std::vector<std::unique_ptr<lb::sim::DeviceSimulator>> devices;
  std::vector<std::unique_ptr<lb::sim::LineController>> controllers;
  const bool play_devices = role != "controller";
  for (const auto& bus_cfg : config->buses) {
    auto bus = lb::can::open_bus(bus_cfg.interface);
    if (!bus) {
      spdlog::error("bus {}: {}", bus_cfg.name, bus.error().message);
      return 1;
    }
    auto loop = std::make_unique<lb::canopen::BusLoop>(std::move(*bus));
    std::vector<const lb::profiles::DeviceConfig*> on_bus;
    for (const auto& dev : config->devices) {
      if (dev.bus != bus_cfg.name || (!only.empty() && std::find(only.begin(), only.end(), dev.name) == only.end()))
        continue;
      on_bus.push_back(&dev);
      if (!play_devices) continue;
      // A device the line file describes but no device could be (a factory mapping of objects it
      // cannot map, ...) stops start-up: it fails at construction or at power-on.
      try {
        devices.push_back(lb::sim::make_simulator(*loop, dev));
        devices.back()->start();
      } catch (const std::runtime_error& e) {
        spdlog::error("{}", e.what());
        return 1;
      }
    }
    if (role != "devices" && !on_bus.empty()) {
      controllers.push_back(std::make_unique<lb::sim::LineController>(*loop, bus_cfg, on_bus));
      controllers.back()->start();
    }
    loops.push_back(std::move(loop));
  }
  for (auto& loop : loops) loop->start();
  spdlog::info("simulating {} device(s){} of line {}", devices.size(),
               controllers.empty() ? "" : " and the line controller", config->line);
  lb::app::run_until_signal(lb::app::duration_ms(duration_s));
  for (auto& loop : loops) loop->stop();
  return 0;
}
