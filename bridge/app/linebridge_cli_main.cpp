// linebridge-cli: watch a device's topics and send it set values, from a terminal.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <thread>

#include "app/arguments.hpp"
#include "app/bus_watch.hpp"
#include "app/dds_options.hpp"
#include "app/eds_tool.hpp"
#include "app/line_topics.hpp"
#include "app/line_config_source.hpp"
#include "app/run_until_signal.hpp"
#include "app/cli_services.hpp"
#include "app/common_text.hpp"
#include "app/saw_text.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"

namespace {

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

// Latest value of something a DDS thread delivers, waited for by the main thread.
template <class T>
class Mailbox {
 public:
  void put(const T& v) {
    {
      std::lock_guard lock(m_);
      value_ = v;
    }
    cv_.notify_all();
  }
  template <class Pred>
  std::optional<T> wait(Clock::duration timeout, Pred pred) {
    std::unique_lock lock(m_);
    if (!cv_.wait_for(lock, timeout, [&] { return value_ && pred(*value_); })) return std::nullopt;
    return value_;
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::optional<T> value_;
};

bool wait_until(Clock::duration timeout, const std::function<bool()>& cond) {
  const auto end = Clock::now() + timeout;
  while (!cond()) {
    if (Clock::now() > end) return false;
    std::this_thread::sleep_for(20ms);
  }
  return true;
}

struct SetOptions {
  std::optional<std::string> program;
  std::optional<double> sync_speed_percent;
  std::optional<double> product_length_m;
  std::optional<std::string> count_mode;
  double timeout_s = 5;
};

int run_set(lb::ddsl::Participant& dds, const std::string& line, const std::string& device, const SetOptions& o) {
  const auto status_topic = lb::ddsl::topic_name(line, device, "status");
  const auto result_topic = lb::ddsl::topic_name(line, device, "setpoint_result");
  const auto setpoint_topic = lb::ddsl::topic_name(line, device, "setpoint");
  const auto timeout = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.timeout_s));

  Mailbox<msg::SawStatus> status;
  Mailbox<msg::SetpointResult> result;
  auto writer = dds.writer<msg::SawSetpointPubSubType>(setpoint_topic, lb::ddsl::QosKind::command);
  if (!writer) return fmt::print(stderr, "{}\n", writer.error().message), 1;
  if (auto r = dds.subscribe<msg::SawStatusPubSubType>(status_topic, lb::ddsl::QosKind::state,
                                                        [&](const msg::SawStatus& s, const auto&) { status.put(s); });
      !r) {
    return fmt::print(stderr, "{}\n", r.error().message), 1;
  }
  if (auto r = dds.subscribe<msg::SetpointResultPubSubType>(
          result_topic, lb::ddsl::QosKind::reply, [&](const msg::SetpointResult& s, const auto&) { result.put(s); });
      !r) {
    return fmt::print(stderr, "{}\n", r.error().message), 1;
  }
  // Fields not given keep the value in force, which the status topic reports; wait for the
  // device to be online so the bridge will not refuse the set value as offline.
  auto current = status.wait(timeout, [](const msg::SawStatus& s) { return s.health().online(); });
  if (!current) {
    fmt::print(stderr, "{}: no online status on {} within {} s (is the bridge running and the device up?)\n", device,
               status_topic, o.timeout_s);
    return 1;
  }
  if (!wait_until(timeout, [&] { return writer->matched() > 0 && dds.matched_writers(result_topic) > 0; })) {
    fmt::print(stderr, "{}: the bridge does not subscribe {}\n", device, setpoint_topic);
    return 1;
  }
  msg::SawSetpoint sp;
  sp.request_id(static_cast<std::uint64_t>(lb::ddsl::now_ns()));
  sp.saw_program_on(o.program ? *o.program == "on" : current->control_word().saw_program_on());
  sp.count_mode(o.count_mode ? (*o.count_mode == "corrugated" ? msg::CORRUGATED_PIPE : msg::SMOOTH_PIPE)
                             : current->control_word().count_mode());
  sp.sync_speed_percent(o.sync_speed_percent.value_or(current->sync_speed_set_percent()));
  sp.product_length_m(o.product_length_m.value_or(current->product_length_set_m()));
  writer->write(sp);
  auto reply = result.wait(timeout, [&](const msg::SetpointResult& r) { return r.request_id() == sp.request_id(); });
  if (!reply) return fmt::print(stderr, "{}: no answer from the bridge within {} s\n", device, o.timeout_s), 1;
  if (!reply->accepted()) return fmt::print(stderr, "{}: set value refused: {}\n", device, reply->reason()), 1;
  fmt::print("{}: accepted: program {}, sync speed {} %, product length {} m\n", device,
             sp.saw_program_on() ? "on" : "off", sp.sync_speed_percent(), sp.product_length_m());
  return 0;
}

struct EchoOptions {
  std::string topic = "status";
  double rate_hz = 2;
  double duration_s = 0;
};

int run_echo(lb::ddsl::Participant& dds, const std::string& line, const std::string& device, const EchoOptions& o) {
  const auto topic = lb::ddsl::topic_name(line, device, o.topic);
  std::mutex print_mutex;
  lb::Result<void> sub = lb::make_error("");
  // Throttle state outlives the subscription's scope: the callback runs until this function returns.
  const auto min_gap = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / o.rate_hz));
  auto last_print = Clock::time_point{};
  std::uint16_t last_word = 0;
  bool last_online = false;
  if (o.topic == "status") {
    sub = dds.subscribe<msg::SawStatusPubSubType>(topic, lb::ddsl::QosKind::state, [&](const msg::SawStatus& s, const auto&) {
      // Throttled, except that every change of a status bit or of the online flag is shown.
      const auto now = Clock::now();
      std::lock_guard lock(print_mutex);
      if (now - last_print < min_gap && s.status_word().raw() == last_word && s.health().online() == last_online) return;
      last_print = now;
      last_word = s.status_word().raw();
      last_online = s.health().online();
      fmt::print("{} {}\n", device, lb::app::to_text(s));
      std::fflush(stdout);
    });
  } else if (o.topic == "cut") {
    sub = dds.subscribe<msg::SawCutPubSubType>(topic, lb::ddsl::QosKind::event, [&](const msg::SawCut& c, const auto&) {
      std::lock_guard lock(print_mutex);
      fmt::print("{} {}\n", device, lb::app::to_text(c));
      std::fflush(stdout);
    });
  } else if (o.topic == "info") {
    sub = dds.subscribe<msg::DeviceInfoPubSubType>(topic, lb::ddsl::QosKind::state, [&](const msg::DeviceInfo& i, const auto&) {
      std::lock_guard lock(print_mutex);
      fmt::print("{} {}\n", device, lb::app::to_text(i));
      std::fflush(stdout);
    });
  } else if (o.topic == "emergency") {
    sub = dds.subscribe<msg::EmergencyPubSubType>(topic, lb::ddsl::QosKind::event, [&](const msg::Emergency& e, const auto&) {
      std::lock_guard lock(print_mutex);
      fmt::print("{} {}\n", device, lb::app::to_text(e));
      std::fflush(stdout);
    });
  } else if (o.topic == "diagnostics") {
    sub = dds.subscribe<msg::DiagnosticsPubSubType>(topic, lb::ddsl::QosKind::state, [&](const msg::Diagnostics& d, const auto&) {
      std::lock_guard lock(print_mutex);
      fmt::print("{}", lb::app::to_text(d));
      std::fflush(stdout);
    });
  } else {
    sub = dds.subscribe<msg::SetpointResultPubSubType>(topic, lb::ddsl::QosKind::reply,
                                                      [&](const msg::SetpointResult& r, const auto&) {
                                                        std::lock_guard lock(print_mutex);
                                                        fmt::print("{} request {}: {}{}\n", device, r.request_id(),
                                                                   r.accepted() ? "accepted" : "refused: ", r.reason());
                                                        std::fflush(stdout);
                                                      });
  }
  if (!sub) return fmt::print(stderr, "{}\n", sub.error().message), 1;
  lb::app::run_until_signal(lb::app::duration_ms(o.duration_s));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  namespace app = lb::app;
  CLI::App cli{"linebridge-cli: read and set the devices of a line over DDS"};
  app::add_conventions(cli, "linebridge-cli");
  cli.require_subcommand(1);
  std::string config_path;
  cli.add_option("-c,--config", config_path, "line configuration (YAML); default: the built-in demo line")
      ->check(app::non_empty_path());
  std::string identity_dir;
  cli.add_option("--identity", identity_dir,
                 "secured line: this client's identity folder (cert.pem, key.pem, permissions.p7s; launch_scripts/pki.sh)")
      ->envname("LINEBRIDGE_IDENTITY");

  std::string device;
  EchoOptions echo;
  auto* echo_cmd = cli.add_subcommand("echo", "print a device's samples as they arrive (Ctrl-C stops)");
  echo_cmd->add_option("device", device, "device name, or 'bridge' for diagnostics")->required();
  echo_cmd->add_option("topic", echo.topic, "status, cut, setpoint_result, info, emergency; diagnostics (device 'bridge')")
      ->check(CLI::IsMember({"status", "cut", "setpoint_result", "info", "emergency", "diagnostics"}))
      ->capture_default_str();
  echo_cmd->add_option("--rate", echo.rate_hz, "status lines per second at most (bit changes always show)")
      ->check(app::positive_at_most(1000))
      ->capture_default_str();
  echo_cmd->add_option("-d,--duration", echo.duration_s, "stop after this many seconds (default 0: until Ctrl-C)")
      ->check(app::duration_seconds());

  SetOptions set;
  auto* set_cmd = cli.add_subcommand("set", "send a saw set value; fields not given keep their value in force");
  set_cmd->add_option("device", device, "device name")->required();
  set_cmd->add_option("--program", set.program, "saw program")->check(CLI::IsMember({"on", "off"}));
  set_cmd->add_option("--sync-speed-percent", set.sync_speed_percent, "saw sync speed set value, 0..100 %");
  set_cmd->add_option("--product-length-m", set.product_length_m, "product length set value in metres");
  set_cmd->add_option("--count-mode", set.count_mode, "smooth or corrugated pipe")->check(CLI::IsMember({"smooth", "corrugated"}));
  set_cmd->add_option("--timeout", set.timeout_s, "seconds to wait for the bridge")
      ->check(app::positive_at_most(3600))
      ->capture_default_str();

  auto* list_cmd = cli.add_subcommand("list", "list the line's buses and devices");

  double timeout_s = 10;
  std::string nmt_command;
  auto* nmt_cmd = cli.add_subcommand("nmt", "send an NMT command to a device (master role)");
  nmt_cmd->add_option("device", device, "device name")->required();
  nmt_cmd->add_option("command", nmt_command)->required()->check(
      CLI::IsMember({"start", "stop", "pre-operational", "reset-node", "reset-communication"}));

  std::uint16_t index = 0;
  std::uint16_t sub = 0;
  std::string type, value;
  auto* read_cmd = cli.add_subcommand("sdo-read", "read an object by SDO: sdo-read DEVICE INDEX SUB TYPE (e.g. 0x1008 0 VISIBLE_STRING)");
  auto* write_cmd = cli.add_subcommand("sdo-write", "write an object by SDO: sdo-write DEVICE INDEX SUB TYPE VALUE");
  for (auto* c : {read_cmd, write_cmd}) {
    c->add_option("device", device, "device name")->required();
    c->add_option("index", index, "object index (0x... for hex)")->required();
    c->add_option("sub", sub, "sub-index")->required()->check(CLI::Range(0, 255));
    c->add_option("type", type, "INTEGER8..64, UNSIGNED8..64, REAL32, REAL64, VISIBLE_STRING, OCTET_STRING")->required();
  }
  write_cmd->add_option("value", value)->required();

  std::string parameter;
  double parameter_value = 0;
  auto* get_cmd = cli.add_subcommand("get", "read a profile object by name in engineering units: get DEVICE NAME");
  auto* put_cmd = cli.add_subcommand("put", "write a profile object by name in engineering units: put DEVICE NAME VALUE");
  for (auto* c : {get_cmd, put_cmd}) {
    c->add_option("device", device, "device name")->required();
    c->add_option("name", parameter, "profile object name, e.g. saw_cut_depth")->required();
  }
  put_cmd->add_option("value", parameter_value)->required();

  auto* identity_cmd = cli.add_subcommand(
      "identity", "read a device's identity (1000h, 1018h) and print it as the identity: lines of its line-file entry");
  identity_cmd->add_option("device", device, "device name")->required();

  std::string command_name;
  auto* press_cmd = cli.add_subcommand("press", "a momentary command, held 100 ms: press DEVICE COMMAND (e.g. manual_cut)");
  press_cmd->add_option("device", device, "device name")->required();
  press_cmd->add_option("command", command_name)->required();
  for (auto* c : {nmt_cmd, read_cmd, write_cmd, get_cmd, put_cmd, press_cmd, identity_cmd}) {
    c->add_option("--timeout", timeout_s, "seconds to wait for the bridge")
        ->check(app::positive_at_most(3600))
        ->capture_default_str();
  }

  std::string bus_name;
  app::WatchOptions watch;
  auto* candump_cmd = cli.add_subcommand(
      "candump", "print the raw frames of a bus of the line (virtual buses too), listen-only, as candump -l writes them");
  candump_cmd->add_option("bus", bus_name, "bus name in the line file")->required();
  candump_cmd->add_option("-d,--duration", watch.duration_s, "stop after this many seconds (default 0: until Ctrl-C)")
      ->check(app::duration_seconds());
  candump_cmd->add_option("-n,--count", watch.count, "stop after this many frames");
  candump_cmd->add_flag("--log", watch.log_only, "bare log lines (for a file canplayer replays), without what each frame is");

  app::TopicsOptions topics;
  auto* topics_cmd = cli.add_subcommand("topics", "list the DDS topics and types of the running line, as discovery reports them");
  topics_cmd->add_option("--wait", topics.wait_s, "seconds of discovery before the list is printed")
      ->check(app::positive_at_most(600))
      ->capture_default_str();
  topics_cmd->add_flag("--all", topics.all, "every topic of the DDS domain, not only this line's");

  app::EdsOptions eds;
  auto* eds_cmd = cli.add_subcommand(
      "eds", "read a device's EDS or DCF file (CiA 306), check it against a profile and print the line-file entries it implies");
  eds_cmd->add_option("file", eds.file, "the EDS or DCF file")->required()->check(CLI::ExistingFile);
  eds_cmd->add_option("--device", eds.device, "check it for this device of the line (its profile, node-ID and PDOs)");
  eds_cmd->add_option("--profile", eds.profile, "or against this profile id (e.g. cia420-4) ...");
  eds_cmd->add_option("--profile-version", eds.profile_version, "... and version (e.g. 3.1)");
  eds_cmd->add_option("--node-id", eds.node_id, "node-ID for $NODEID (default: a DCF's, else the device's)")->check(CLI::Range(1, 127));
  if (const int code = app::parse(cli, argc, argv); code >= 0) return code;
  spdlog::set_level(spdlog::level::warn);

  lb::app::block_stop_signals();
  const auto registry = lb::profiles::ProfileRegistry::builtin();
  auto config = lb::app::load_config(config_path, registry);
  if (!config) return fmt::print(stderr, "{}\n", config.error().message), 2;
  if (candump_cmd->parsed()) return app::watch_bus(*config, bus_name, watch);
  if (eds_cmd->parsed()) return app::run_eds(*config, registry, eds);
  if (topics_cmd->parsed()) {
    auto options = app::client_participant_options(*config, "linebridge-cli topics", identity_dir);
    if (!options) return fmt::print(stderr, "{}\n", options.error().message), app::kExitUsage;
    return app::list_topics(*config, *options, topics);
  }
  if (list_cmd->parsed()) {
    for (const auto& b : config->buses) fmt::print("bus {} on {} ({})\n", b.name, b.interface, lb::profiles::to_string(b.role));
    for (const auto& d : config->devices) {
      fmt::print("device {} on {} node {}: {} {}\n", d.name, d.bus, d.node_id, d.resolved_profile->device, d.resolved_profile->key());
    }
    return 0;
  }
  const bool bridge_topic = echo_cmd->parsed() && device == lb::ddsl::kBridgeNamespace && echo.topic == "diagnostics";
  const auto* dev = config->device(device);
  if (dev == nullptr && !bridge_topic) return fmt::print(stderr, "no device {} in line {} (try: list)\n", device, config->line), 2;
  const bool saw_only = set_cmd->parsed() || (echo_cmd->parsed() && (echo.topic == "status" || echo.topic == "cut"));
  if (saw_only && dev->resolved_profile->device != "saw") {
    return fmt::print(stderr, "{}: the CLI shows and sets saws only so far (this is a {})\n", device,
                      dev->resolved_profile->device), 2;
  }
  auto options = lb::app::client_participant_options(*config, "linebridge-cli", identity_dir);
  if (!options) return fmt::print(stderr, "{}\n", options.error().message), 2;
  auto dds = lb::ddsl::Participant::create_checked(*options);
  if (!dds) return fmt::print(stderr, "{}\n", dds.error().message), dds.error().configuration ? 2 : 1;
  const lb::app::ServiceTarget target{**dds, config->line, device,
                                      std::chrono::milliseconds(static_cast<long>(timeout_s * 1000))};
  if (nmt_cmd->parsed()) return lb::app::call_nmt(target, nmt_command);
  if (read_cmd->parsed()) return lb::app::call_sdo_read(target, index, static_cast<std::uint8_t>(sub), type);
  if (write_cmd->parsed()) return lb::app::call_sdo_write(target, index, static_cast<std::uint8_t>(sub), type, value);
  if (get_cmd->parsed()) return lb::app::call_get_parameter(target, parameter);
  if (put_cmd->parsed()) return lb::app::call_set_parameter(target, parameter, parameter_value);
  if (press_cmd->parsed()) return lb::app::call_command(target, command_name);
  if (identity_cmd->parsed()) return lb::app::call_identity(target);
  return echo_cmd->parsed() ? run_echo(**dds, config->line, device, echo) : run_set(**dds, config->line, device, set);
}
