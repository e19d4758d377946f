// linebridge-cli: watch a line's devices and command them over DDS, from a terminal, whatever the
// device type. Exit codes: app/cli_exit.hpp.
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "app/arguments.hpp"
#include "app/bus_watch.hpp"
#include "app/cli_echo.hpp"
#include "app/cli_exit.hpp"
#include "app/cli_services.hpp"
#include "app/cli_set.hpp"
#include "app/dds_options.hpp"
#include "app/eds_tool.hpp"
#include "app/line_config_source.hpp"
#include "app/line_topics.hpp"
#include "app/run_until_signal.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "profiles/device_types.hpp"

namespace {

using lb::app::kExitUsage;

struct FeederArgs {
  unsigned feeder = 0;
  std::string name;  // command, test, weft insertion type
  unsigned parameter = 0;
  std::vector<std::string> items;  // function settings, trigger sources
  std::optional<unsigned> number, color;
};

// The set options given that a device type does not take.
bool set_options_fit(const std::string& type, CLI::App& set_cmd) {
  const auto given = [&](const char* name) { return set_cmd.get_option(name)->count() > 0; };
  using lb::profiles::Behaviour;
  const std::vector<std::pair<const char*, Behaviour>> owners = {{"--program", Behaviour::saw},
                                                                 {"--wall-thickening", Behaviour::saw},
                                                                 {"--sync-speed-percent", Behaviour::saw},
                                                                 {"--product-length-m", Behaviour::saw},
                                                                 {"--count-mode", Behaviour::saw},
                                                                 {"--extruder", Behaviour::drive},
                                                                 {"--speed-percent", Behaviour::drive},
                                                                 {"--loom-status", Behaviour::feeder},
                                                                 {"--maximum-speed", Behaviour::feeder},
                                                                 {"--loom-width-m", Behaviour::feeder},
                                                                 {"--trigger-signal", Behaviour::feeder},
                                                                 {"--picks", Behaviour::feeder},
                                                                 {"--outputs", Behaviour::feeder}};
  const auto* entry = lb::profiles::find_device_type(type);
  for (const auto& [option, owner] : owners) {
    if (given(option) && (entry == nullptr || entry->behaviour != owner)) {
      fmt::print(stderr, "{} is not a set value of a {} ({})\n", option, type, lb::app::set_options_of(type));
      return false;
    }
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  namespace app = lb::app;
  CLI::App cli{"linebridge-cli: watch and command the devices of a line over DDS"};
  app::add_conventions(cli, "linebridge-cli", app::kCliExitCodes);
  cli.require_subcommand(1);
  // --config, --identity (and each subcommand's --timeout) anywhere on the command line.
  cli.fallthrough();
  std::string config_path;
  lb::app::add_config_option(cli, config_path);
  std::string identity_dir;
  cli.add_option(
         "--identity", identity_dir,
         "secured line: this client's identity folder (cert.pem, key.pem, permissions.p7s; launch_scripts/pki.sh)")
      ->envname("LINEBRIDGE_IDENTITY");

  std::string device;
  lb::app::EchoOptions echo;
  auto* echo_cmd = cli.add_subcommand("echo", "print a device's samples as they arrive (Ctrl-C stops)");
  echo_cmd->add_option("device", device, "device name, or 'bridge' for diagnostics")->required();
  echo_cmd
      ->add_option("topic", echo.topic,
                   "saw: status, cut, setpoint_result, info, emergency; puller, corrugator: status, setpoint_result, "
                   "info, emergency; feeder: status, unwinding, feeder_error, loom_result, info, emergency; "
                   "bridge: diagnostics")
      ->capture_default_str();
  echo_cmd->add_option("--rate", echo.rate_hz, "status lines per second at most (bit changes always show)")
      ->check(app::positive_at_most(1000))
      ->capture_default_str();
  echo_cmd->add_option("-d,--duration", echo.duration_s, "stop after this many seconds (default 0: until Ctrl-C)")
      ->check(app::duration_seconds());

  lb::app::SetOptions set;
  auto* set_cmd = cli.add_subcommand("set", "send a device's set values; fields not given keep the value in force");
  set_cmd->add_option("device", device, "device name")->required();
  set_cmd->add_option("--program", set.program, "saw program")->check(CLI::IsMember({"on", "off"}));
  set_cmd->add_option("--wall-thickening", set.wall_thickening, "saw: wall-thickening (6020h bit 1)")
      ->check(CLI::IsMember({"on", "off"}));
  set_cmd->add_option("--sync-speed-percent", set.sync_speed_percent, "saw sync speed set value, 0..100 %");
  set_cmd->add_option("--product-length-m", set.product_length_m, "saw product length set value in metres");
  set_cmd->add_option("--count-mode", set.count_mode, "saw: smooth or corrugated pipe")
      ->check(CLI::IsMember({"smooth", "corrugated"}));
  set_cmd->add_option("--extruder", set.extruder, "puller, corrugator: extruder running (6020h bit 6)")
      ->check(CLI::IsMember({"running", "stopped"}));
  set_cmd->add_option("--speed-percent", set.speed_percent, "puller, corrugator: speed set value 6002h, -100..100 %");
  set_cmd->add_option("--loom-status", set.loom_status,
                      "feeder: 600Ah by name, e.g. start_advice (with the weft filling in force)");
  set_cmd->add_option("--maximum-speed", set.maximum_speed_per_min,
                      "feeder: 6004h maximum speed, 1/min (with --loom-status)");
  set_cmd->add_option("--loom-width-m", set.loom_width_m, "feeder: 6004h loom width in metres (with --loom-status)");
  set_cmd->add_option("--trigger-signal", set.trigger_signal, "feeder: 600Bh by name, e.g. angle_trigger");
  set_cmd->add_option("--picks", set.picks, "feeder: five 600Ch codes, e.g. --picks 0x01 0x02 0x03 0x04 0x05")
      ->expected(5);
  set_cmd->add_option("--outputs", set.outputs, "feeder: 600Dh output groups 1..n (RPDO3), bit k = line k+1")
      ->expected(1, 8);
  set_cmd
      ->add_option("--timeout", set.timeout_s,
                   "seconds to wait for the bridge's answer (unanswered, the set value is written again every second)")
      ->check(app::positive_at_most(3600))
      ->capture_default_str();

  auto* list_cmd = cli.add_subcommand("list", "list the line's buses and devices");

  double timeout_s = 10;
  std::string nmt_command;
  auto* nmt_cmd = cli.add_subcommand("nmt", "send an NMT command to a device (master role)");
  nmt_cmd->add_option("device", device, "device name")->required();
  nmt_cmd->add_option("command", nmt_command)
      ->required()
      ->check(CLI::IsMember({"start", "stop", "pre-operational", "reset-node", "reset-communication"}));

  std::uint16_t index = 0;
  std::uint16_t sub = 0;
  std::string type, value;
  auto* read_cmd = cli.add_subcommand(
      "sdo-read", "read an object by SDO: sdo-read DEVICE INDEX SUB TYPE (e.g. 0x1008 0 VISIBLE_STRING)");
  auto* write_cmd = cli.add_subcommand("sdo-write", "write an object by SDO: sdo-write DEVICE INDEX SUB TYPE VALUE");
  for (auto* c : {read_cmd, write_cmd}) {
    c->add_option("device", device, "device name")->required();
    c->add_option("index", index, "object index (0x... for hex)")->required();
    c->add_option("sub", sub, "sub-index")->required()->check(CLI::Range(0, 255));
    c->add_option("type", type, "INTEGER8..64, UNSIGNED8..64, REAL32, REAL64, VISIBLE_STRING, OCTET_STRING")
        ->required();
  }
  write_cmd->add_option("value", value)->required();

  std::string parameter;
  double parameter_value = 0;
  auto* get_cmd = cli.add_subcommand("get", "read a profile object by name in engineering units: get DEVICE NAME");
  auto* put_cmd = cli.add_subcommand("put",
                                     "write a profile object by name in engineering units: put DEVICE NAME VALUE");
  for (auto* c : {get_cmd, put_cmd}) {
    c->add_option("device", device, "device name")->required();
    c->add_option("name", parameter, "profile object name, e.g. saw_cut_depth")->required();
  }
  put_cmd->add_option("value", parameter_value)->required();

  auto* identity_cmd = cli.add_subcommand(
      "identity", "read a device's identity (1000h, 1018h) and print it as the identity: lines of its line-file entry");
  identity_cmd->add_option("device", device, "device name")->required();

  std::string command_name;
  auto* press_cmd = cli.add_subcommand(
      "press", "a momentary command, on the bus for at least 100 ms: press DEVICE COMMAND (e.g. manual_cut)");
  press_cmd->add_option("device", device, "device name")->required();
  press_cmd->add_option("command", command_name)->required();

  // A feeder box's typed services.
  FeederArgs fa;
  auto* fcommand_cmd = cli.add_subcommand("feeder-command",
                                          "600Eh: feeder-command BOX FEEDER COMMAND (e.g. reset, operation_mode)");
  auto* ftest_cmd = cli.add_subcommand("feeder-test",
                                       "600Fh: feeder-test BOX FEEDER TEST [PARAMETER] (motor_test 5..100 Hz, ...)");
  auto* ffunctions_cmd = cli.add_subcommand("feeder-functions", "6001h: feeder-functions BOX FEEDER FUNCTION=STATE...");
  auto* fassign_cmd = cli.add_subcommand("feeder-assignment",
                                         "6011h/6012h: feeder-assignment BOX FEEDER [--number N] [--color C]");
  for (auto* c : {fcommand_cmd, ftest_cmd, ffunctions_cmd, fassign_cmd}) {
    c->add_option("box", device, "the feeder box's device name")->required();
    c->add_option("feeder", fa.feeder, "feeder number 1..254")->required()->check(CLI::Range(1, 254));
  }
  fcommand_cmd->add_option("command", fa.name)->required();
  fcommand_cmd->add_option("--code", fa.parameter, "manufacturer_specific: its code, 09h..5Fh");
  ftest_cmd->add_option("test", fa.name, "no_test, motor_test, pin_test, strobo_function")->required();
  ftest_cmd->add_option("parameter", fa.parameter, "Hz, or 0/1")->check(CLI::Range(0, 255));
  ffunctions_cmd->add_option("settings", fa.items, "e.g. yarn_break_sensor=active winding_direction=z")->required();
  fassign_cmd->add_option("--number", fa.number, "system feeder number")->check(CLI::Range(0, 255));
  fassign_cmd->add_option("--color", fa.color, "colour")->check(CLI::Range(0, 255));
  auto* weft_cmd = cli.add_subcommand("weft-insertion-type",
                                      "6002h: weft-insertion-type BOX TYPE (projectile, rapier, ...)");
  weft_cmd->add_option("box", device, "the feeder box's device name")->required();
  weft_cmd->add_option("type", fa.name)->required();
  auto* trigger_cmd = cli.add_subcommand("trigger-source",
                                         "6005h sub 2: trigger-source BOX [SOURCE...] (none: no source)");
  trigger_cmd->add_option("box", device, "the feeder box's device name")->required();
  trigger_cmd->add_option("sources", fa.items, "e.g. angle_trigger_via_canopen");
  const std::vector<CLI::App*> feeder_cmds{fcommand_cmd, ftest_cmd, ffunctions_cmd, fassign_cmd, weft_cmd, trigger_cmd};

  for (auto* c : {nmt_cmd, read_cmd, write_cmd, get_cmd, put_cmd, press_cmd, identity_cmd, fcommand_cmd, ftest_cmd,
                  ffunctions_cmd, fassign_cmd, weft_cmd, trigger_cmd}) {
    c->add_option("--timeout", timeout_s,
                  "seconds to wait for the bridge's answer (unanswered, the request is asked again every second; the "
                  "bridge runs it once)")
        ->check(app::positive_at_most(3600))
        ->capture_default_str();
  }

  std::string bus_name;
  app::WatchOptions watch;
  auto* candump_cmd = cli.add_subcommand(
      "candump",
      "print the raw frames of a bus of the line (virtual buses too), listen-only, as candump -l writes them");
  candump_cmd->add_option("bus", bus_name, "bus name in the line file")->required();
  candump_cmd->add_option("-d,--duration", watch.duration_s, "stop after this many seconds (default 0: until Ctrl-C)")
      ->check(app::duration_seconds());
  candump_cmd->add_option("-n,--count", watch.count, "stop after this many frames");
  candump_cmd->add_flag("--log", watch.log_only,
                        "bare log lines (for a file canplayer replays), without what each frame is");

  app::TopicsOptions topics;
  auto* topics_cmd = cli.add_subcommand("topics",
                                        "list the DDS topics and types of the running line, as discovery reports them");
  topics_cmd->add_option("--wait", topics.wait_s, "seconds of discovery before the list is printed")
      ->check(app::positive_at_most(600))
      ->capture_default_str();
  topics_cmd->add_flag("--all", topics.all, "every topic of the DDS domain, not only this line's");

  app::EdsOptions eds;
  auto* eds_cmd = cli.add_subcommand("eds", "read a device's EDS or DCF file (CiA 306), check it against a profile and "
                                            "print the line-file entries it implies");
  eds_cmd->add_option("file", eds.file, "the EDS or DCF file")->required()->check(CLI::ExistingFile);
  eds_cmd->add_option("--device", eds.device, "check it for this device of the line (its profile, node-ID and PDOs)");
  eds_cmd->add_option("--profile", eds.profile, "or against this profile id (e.g. cia420-4) ...");
  eds_cmd->add_option("--profile-version", eds.profile_version, "... and version (e.g. 3.1)");
  eds_cmd->add_option("--node-id", eds.node_id, "node-ID for $NODEID (default: a DCF's, else the device's)")
      ->check(CLI::Range(1, 127));
  if (const int code = app::parse(cli, argc, argv); code >= 0) return code;
  spdlog::set_level(spdlog::level::warn);

  lb::app::block_stop_signals();
  // A reader that goes away (`linebridge-cli echo ... | head`) must end this process cleanly: killed
  // by SIGPIPE it would leave its DDS participant behind, matched to the bridge's writers until
  // its lease runs out. A failed write to stdout ends the watching commands instead (exit 0).
  std::signal(SIGPIPE, SIG_IGN);
  const auto registry = lb::profiles::ProfileRegistry::builtin();
  auto config = lb::app::load_config(config_path, registry);
  if (!config) return fmt::print(stderr, "{}\n", config.error().message), kExitUsage;
  if (candump_cmd->parsed()) return app::watch_bus(*config, bus_name, watch);
  if (eds_cmd->parsed()) return app::run_eds(*config, registry, eds);
  if (topics_cmd->parsed()) {
    auto options = app::client_participant_options(*config, "linebridge-cli topics", identity_dir);
    if (!options) return fmt::print(stderr, "{}\n", options.error().message), app::kExitUsage;
    return app::list_topics(*config, *options, topics);
  }
  if (list_cmd->parsed()) {
    for (const auto& b : config->buses)
      fmt::print("bus {} on {} ({})\n", b.name, b.interface, lb::profiles::to_string(b.role));
    for (const auto& d : config->devices) {
      fmt::print("device {} on {} node {}: {} {}\n", d.name, d.bus, d.node_id, d.resolved_profile->device,
                 d.resolved_profile->key());
    }
    return lb::app::kExitOk;
  }
  const bool bridge_topic = echo_cmd->parsed() && device == lb::ddsl::kBridgeNamespace;
  const auto* dev = config->device(device);
  if (dev == nullptr && !bridge_topic) {
    return fmt::print(stderr, "no device {} in line {} (try: list)\n", device, config->line), kExitUsage;
  }
  const std::string device_type = bridge_topic ? std::string(lb::ddsl::kBridgeNamespace)
                                               : dev->resolved_profile->device;
  if (echo_cmd->parsed() && bridge_topic && echo.topic == "status") echo.topic = "diagnostics";
  if (set_cmd->parsed() && !set_options_fit(device_type, *set_cmd)) return kExitUsage;
  const auto* type_entry = lb::profiles::find_device_type(device_type);
  const bool is_feeder_box = type_entry != nullptr && type_entry->behaviour == lb::profiles::Behaviour::feeder;
  for (auto* c : feeder_cmds) {
    if (c->parsed() && !is_feeder_box) {
      return fmt::print(stderr, "{}: {} is for a feeder box; {} is a {}\n", c->get_name(), device, device, device_type),
             kExitUsage;
    }
  }

  auto options = lb::app::client_participant_options(*config, "linebridge-cli", identity_dir);
  if (!options) return fmt::print(stderr, "{}\n", options.error().message), kExitUsage;
  auto dds = lb::ddsl::Participant::create_checked(*options);
  if (!dds)
    return fmt::print(stderr, "{}\n", dds.error().message),
           dds.error().configuration ? kExitUsage : lb::app::kExitNoAnswer;
  const lb::app::ServiceTarget target{**dds, config->line, device,
                                      std::chrono::milliseconds(static_cast<long>(timeout_s * 1000))};
  if (nmt_cmd->parsed()) return lb::app::call_nmt(target, nmt_command);
  if (read_cmd->parsed()) return lb::app::call_sdo_read(target, index, static_cast<std::uint8_t>(sub), type);
  if (write_cmd->parsed()) return lb::app::call_sdo_write(target, index, static_cast<std::uint8_t>(sub), type, value);
  if (get_cmd->parsed()) return lb::app::call_get_parameter(target, parameter);
  if (put_cmd->parsed()) return lb::app::call_set_parameter(target, parameter, parameter_value);
  if (press_cmd->parsed()) return lb::app::call_command(target, command_name);
  if (identity_cmd->parsed()) return lb::app::call_identity(target);
  if (fcommand_cmd->parsed()) return lb::app::call_feeder_command(target, fa.feeder, fa.name, fa.parameter);
  if (ftest_cmd->parsed()) return lb::app::call_feeder_test(target, fa.feeder, fa.name, fa.parameter);
  if (ffunctions_cmd->parsed()) return lb::app::call_feeder_functions(target, fa.feeder, fa.items);
  if (fassign_cmd->parsed()) return lb::app::call_feeder_assignment(target, fa.feeder, fa.number, fa.color);
  if (weft_cmd->parsed()) return lb::app::call_weft_insertion_type(target, fa.name);
  if (trigger_cmd->parsed()) return lb::app::call_trigger_source(target, fa.items);
  if (echo_cmd->parsed()) return lb::app::run_echo(**dds, config->line, device, device_type, echo);
  return lb::app::run_set(**dds, config->line, device, device_type, set);
}
