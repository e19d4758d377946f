// linebridge: the gateway process. Serves the buses and devices of one line configuration on DDS.
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include "app/arguments.hpp"
#include "app/async_log.hpp"
#include "app/dds_options.hpp"
#include "app/dds_side.hpp"
#include "app/dds_supervisor.hpp"
#include "app/line_bridge.hpp"
#include "app/line_check.hpp"
#include "app/line_config_source.hpp"
#include "app/restart_pacing.hpp"
#include "app/run_until_signal.hpp"
#include "app/service_notifier.hpp"
#include "dds/fastdds_log.hpp"
#include "dds/security_files.hpp"
#include "link/bus_channel.hpp"

#include <linux/close_range.h>
#include <pwd.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>

#include <filesystem>
#include <optional>
#include <vector>

namespace {

// --part both: a private directory for the channel (mode 0700), removed at exit.
class PrivateDir {
 public:
  PrivateDir() {
    const char* base = std::getenv("RUNTIME_DIRECTORY");
    if (base == nullptr) base = std::getenv("XDG_RUNTIME_DIR");
    std::string tmpl = std::string(base != nullptr ? base : "/tmp") + "/linebridge-XXXXXX";
    if (::mkdtemp(tmpl.data()) != nullptr) path_ = tmpl;
  }
  ~PrivateDir() {
    std::error_code ignored;
    if (!path_.empty()) std::filesystem::remove_all(path_, ignored);
  }
  PrivateDir(const PrivateDir&) = delete;
  PrivateDir& operator=(const PrivateDir&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

// --dds-user: a user name or a numeric uid.
std::optional<uid_t> user_id(const std::string& user) {
  if (!user.empty() && user.find_first_not_of("0123456789") == std::string::npos) {
    uid_t uid = 0;
    const auto [end, ec] = std::from_chars(user.data(), user.data() + user.size(), uid);
    if (ec != std::errc{} || end != user.data() + user.size()) return std::nullopt;
    return uid;
  }
  passwd pw{};
  passwd* found = nullptr;
  std::vector<char> buffer(16384);
  if (::getpwnam_r(user.c_str(), &pw, buffer.data(), buffer.size(), &found) != 0 || found == nullptr)
    return std::nullopt;
  return found->pw_uid;
}

std::string own_executable() {
  std::error_code ec;
  auto p = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("/proc/self/exe") : p.string();
}

// run()'s answer when a standby bus lost a negotiation (LineBridge::stepped_back): start again.
constexpr int kRunAgain = -1;

int run(int argc, char** argv);

}  // namespace

// A bridge that stepped back starts again as the standby it is configured to be, in the same
// process (a service manager sees no exit, its watchdog no gap): once everything of this run is
// gone (its DDS process, channel, buses), the executable replaces itself with its own arguments.
int main(int argc, char** argv) {
  const int code = run(argc, argv);
  if (code != kRunAgain) return code;
  ::close_range(3, ~0U, CLOSE_RANGE_CLOEXEC);  // nothing of this run reaches the next
  ::execv("/proc/self/exe", argv);
  std::fprintf(stderr, "linebridge: cannot start again as a standby: %s\n", std::strerror(errno));
  return lb::app::kExitLoopFailed;
}

namespace {

int run(int argc, char** argv) {
  namespace app = lb::app;
  CLI::App cli{"linebridge: CANopen extrusion-line devices on DDS"};
  app::add_conventions(cli, "linebridge", app::kBridgeExitCodes);
  std::string config_path;
  std::string check_path;
  std::string peer_path;
  double duration_s = 0;
  std::string log_level = "info";
  std::string part = "both";
  std::string channel_path;
  bool lock_memory = false;
  std::string dds_user;
  double absent_alarm_s = 30;
  std::string pace_starts;
  lb::app::add_config_option(cli, config_path);
  cli.add_option("--check", check_path,
                 "check a line configuration (and its profile, DDS profile and security files) as start-up would, "
                 "print its buses, devices and DDS topics, and exit (0 valid, 2 not); touches neither CAN nor DDS")
      ->check(app::non_empty_path());
  cli.add_option("--peer", peer_path,
                 "with --check: the line file of the other bridge of a redundant pair (docs/redundancy.md): both "
                 "checked, then the pair (the same line, buses and devices, both standby, different "
                 "flying-master priorities)")
      ->check(app::non_empty_path());
  cli.add_option("-d,--duration", duration_s, "stop after this many seconds (default 0: run until SIGINT/SIGTERM)")
      ->check(app::duration_seconds());
  cli.add_option("--part", part,
                 "both (default: the bus process, which starts its DDS process and restarts it), bus (CAN, the "
                 "CANopen master, no DDS), dds (the DDS side of a running bus process), single (one process, for "
                 "comparison)")
      ->check(CLI::IsMember({"both", "bus", "dds", "single"}))
      ->capture_default_str();
  cli.add_option("--channel", channel_path,
                 "the channel between the bus and DDS processes (a socket path); --part bus and dds need it, both "
                 "makes a private one")
      ->check(app::non_empty_path());
  cli.add_option("--dds-user", dds_user,
                 "--part bus: the user (name or uid) whose process alone may be the DDS side on the channel (default: "
                 "this process's own; the package's units: linebridge-dds)");
  cli.add_option("--dds-absent-alarm", absent_alarm_s,
                 "--part bus or both: with no DDS side for this many seconds, an alarm in the log and the line's "
                 "diagnostics (0: never)")
      ->check(CLI::Range(0.0, 86400.0))
      ->capture_default_str();
  cli.add_option("--pace-starts", pace_starts,
                 "--part dds under a service manager that restarts it: keep the record of this process's starts in "
                 "this file and wait before starting when they come too often (a back-off: 20 restarts a minute at "
                 "once, then 1 s doubling to 30 s)");
  cli.add_flag("--lock-memory", lock_memory,
               "the bus process locks its memory (mlockall): its loops never wait for a page from swap (needs "
               "LimitMEMLOCK or CAP_IPC_LOCK; refused: a warning, the bus runs on)");
  cli.add_option("--log-level", log_level, "trace, debug, info, warn, error, critical, off")
      ->check(app::log_level())
      ->capture_default_str();
  if (const int code = app::parse(cli, argc, argv); code >= 0) return code;
  spdlog::set_level(spdlog::level::from_str(log_level));
  const std::string pattern = std::string("%H:%M:%S.%e [") + (part == "dds" ? "dds" : "bridge") + "] %^%l%$ %v";
  spdlog::set_pattern(pattern);
  if ((part == "bus" || part == "dds") && channel_path.empty()) {
    spdlog::error("--part {} needs --channel PATH", part);
    return app::kExitUsage;
  }
  if (!dds_user.empty() && part != "bus") {
    spdlog::error("--dds-user is for --part bus (under --part both the DDS process is this process's child)");
    return app::kExitUsage;
  }
  if (cli.get_option("--dds-absent-alarm")->count() > 0 && part != "bus" && part != "both") {
    spdlog::error("--dds-absent-alarm is for --part bus or both (the bus process raises it)");
    return app::kExitUsage;
  }
  if (!pace_starts.empty() && part != "dds") {
    spdlog::error("--pace-starts is for --part dds (--part both paces its DDS processes itself)");
    return app::kExitUsage;
  }
  lb::link::PeerRule peer_rule;  // this process's user; --part both: its own child only
  peer_rule.own_child_only = part == "both";
  if (!dds_user.empty()) {
    const auto uid = user_id(dds_user);
    if (!uid) {
      spdlog::error("--dds-user {}: no such user", dds_user);
      return app::kExitUsage;
    }
    peer_rule.uid = *uid;
  }

  const auto registry = lb::profiles::ProfileRegistry::builtin();
  if (!peer_path.empty() && check_path.empty()) {
    spdlog::error("--peer is for --check (linebridge --check FILE --peer FILE)");
    return app::kExitUsage;
  }
  if (!check_path.empty()) {
    spdlog::set_level(spdlog::level::warn);  // the summary says it all; the gateways' start-up lines would not
    if (!peer_path.empty()) return app::check_pair(check_path, peer_path, registry, stdout, stderr);
    return app::check_line(check_path, registry, stdout, stderr);
  }

  // From here on no bus loop waits for the log.
  // Before the log's thread: every thread blocks the stop signals, so that request_stop()'s SIGUSR1
  // (a loop that failed, a bus that stepped back) ends the wait below instead of the process.
  app::block_stop_signals();
  const app::AsyncLog async_log(pattern, part == "dds" ? app::AsyncLog::kDdsQueue : app::AsyncLog::kBusQueue);
  // Before anything costly (the line file, the participant): a DDS process restarted again and
  // again waits here, as its record of starts says. Supervised (--part both), its parent paces it.
  if (part == "dds" && !pace_starts.empty() && std::getenv(app::kBusPidEnv) == nullptr &&
      !app::pace_start(pace_starts)) {
    return app::kExitOk;  // stopped while it waited
  }
  auto config = app::load_config(config_path, registry);
  if (!config) {
    spdlog::error("{}", config.error().message);
    return app::kExitUsage;
  }
  if (part != "dds") spdlog::info("serving {}", app::config_source_text(config_path));
  for (const auto& w : config->warnings) spdlog::warn("{}", w);
  // Fast DDS's warnings (a reader refusing samples among them) and errors in this log, rate-limited.
  const lb::ddsl::FastDdsLogRoute fastdds_log;
  const auto dds_options = app::bridge_participant_options(*config);
  if (dds_options.security && part != "dds") {
    for (const auto& w : lb::ddsl::security_warnings(*dds_options.security)) spdlog::warn("DDS security: {}", w);
  }
  if (part == "dds") {
    return app::run_dds_side(dds_options, config->line, config->observability, channel_path,
                             app::duration_ms(duration_s));
  }
  // The bus process never listens: in one process there is no DDS process to serve the page from.
  if (part == "single" && config->observability.enabled) {
    spdlog::warn("observability: --part single serves no status page and no metrics (only the DDS process of --part "
                 "both or dds does; the bus process never listens)");
  }

  // A standby's DDS side serves only once it masters a bus (docs/redundancy.md): the split's channel
  // holds it back; in one process nothing would.
  if (part == "single" && std::any_of(config->buses.begin(), config->buses.end(),
                                      [](const auto& b) { return b.role == lb::profiles::BusRole::standby; })) {
    spdlog::error("a bus in the standby role needs the bus and DDS sides apart (--part both, or bus and dds)");
    return app::kExitUsage;
  }
  std::unique_ptr<lb::link::BusChannel> channel;
  std::unique_ptr<lb::ddsl::Participant> dds;
  std::optional<PrivateDir> private_dir;
  if (part == "single") {
    // DDS first: a secured participant that cannot prove security is in force is a configuration
    // error (exit 2), like a bad security file or DDS profile; nothing runs unsecured by mistake.
    auto created = lb::ddsl::Participant::create_checked(dds_options);
    if (!created) {
      spdlog::error("{}", created.error().message);
      return created.error().configuration ? app::kExitUsage : app::kExitFailure;
    }
    if (dds_options.security) spdlog::info("{}", app::security_summary(dds_options));
    dds = std::move(*created);
  } else {
    // The security files are checked before the buses open (the DDS process proves security in
    // force): a bad file is a configuration error here too, and no device is started for nothing.
    if (dds_options.security) {
      if (auto files = lb::ddsl::check_security_files(*dds_options.security, dds_options.domain); !files) {
        spdlog::error("{}", files.error().message);
        return app::kExitUsage;
      }
    }
    if (part == "both") {
      private_dir.emplace();
      if (private_dir->path().empty()) {
        spdlog::error("cannot make a private directory for the channel");
        return app::kExitFailure;
      }
      channel_path = private_dir->path() + "/channel.sock";
    }
    lb::link::BusChannel::Options channel_options{channel_path, config->line, lb::ddsl::draw_incarnation()};
    channel_options.peer = peer_rule;
    channel_options.absent_alarm = std::chrono::milliseconds(static_cast<std::int64_t>(absent_alarm_s * 1000));
    auto opened = lb::link::BusChannel::open(std::move(channel_options));
    if (!opened) {
      spdlog::error("{}", opened.error().message);
      return app::kExitFailure;
    }
    channel = std::move(*opened);
    dds = lb::ddsl::Participant::over_channel(dds_options, *channel);
  }
  // The DDS process starts now, beside the line's creation and boot: its participant (about half
  // a second) is ready when the channel first serves it. Until then it waits in the channel's
  // backlog: it is accepted only once every endpoint is declared (channel->start() below).
  std::optional<app::DdsSupervisor> supervisor;
  if (part == "both") {
    std::vector<std::string> dds_argv{own_executable(), "--part",      "dds",    "--channel",
                                      channel_path,     "--log-level", log_level};
    if (!config_path.empty())
      dds_argv.insert(dds_argv.end(), {"--config", std::filesystem::absolute(config_path).string()});
    supervisor.emplace(
        std::move(dds_argv), [c = channel.get()] { return c->counters().connects; },
        [c = channel.get()](pid_t pid, std::string why) { c->report_end(pid, std::move(why)); });
  }
  auto bridge = app::LineBridge::create(*config, std::move(dds));
  if (lock_memory && bridge) {
    // MCL_ONFAULT: every page resident now is locked now, every other page when it is first
    // touched, and none is ever swapped out. Without it the kernel faulted in and pinned the
    // whole of every mapping, each thread's 8 MiB stack included: 149.5 MB resident at 8 x 30
    // saws against 26-34 MB unlocked. What it gives up: a page never touched before (a rarely
    // taken path's code) costs one fault on its first use, once; the boot has run the loops' own.
    if (::mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) == 0) {
      spdlog::info("memory locked (mlockall, each page from its first use)");
    } else {
      spdlog::warn("--lock-memory: mlockall refused ({}); the bus runs on with pageable memory", std::strerror(errno));
    }
  }
  if (!bridge) {
    spdlog::error("start-up failed: {}", bridge.error().message);
    return app::kExitFailure;
  }
  for (const auto& note : (*bridge)->dds().site_notes()) spdlog::warn("DDS profiles: {}", note);
  // The DDS side serves once this bridge masters a bus: at once, or when a standby takes over
  // (until then it waits in the channel's backlog, its participant ready; docs/redundancy.md).
  if (channel) (*bridge)->on_mastering([c = channel.get()] { c->start(); });
  (*bridge)->start();
  spdlog::info("line {}: {} bus(es), {} device(s), DDS domain {}{}{}{}", config->line, config->buses.size(),
               config->devices.size(), config->dds.domain, config->dds.localhost_only ? " (localhost only)" : "",
               config->dds.discovery_servers.empty() ? "" : ", through discovery servers",
               config->dds.security ? ", secured" : "");
  app::ServiceNotifier notifier((*bridge)->watched_loops());
  if (notifier.watchdog().count() > 0) {
    spdlog::info("systemd watchdog: every bus loop must show progress within {} ms",
                 notifier.watchdog().count() / 1000);
  }
  const int sig = app::run_until_signal(app::duration_ms(duration_s));
  const bool dds_refused = supervisor && supervisor->refused_configuration();
  const bool again = !dds_refused && (*bridge)->stepped_back();
  // A step back is no stop to a service manager: this process goes on under its PID and its next
  // image says READY=1 again. STOPPING=1 here had systemd wait TimeoutStopSec for an exit that never
  // came, then kill the new image and restart the unit (systemd-vm.sh --takeover).
  if (again) {
    notifier.restarting("another master won the bus: starting again as a standby");
  } else {
    notifier.stopping();
  }
  if (channel) channel->stopping();  // the DDS process is ended just below: a clean stop, not a loss
  supervisor.reset();
  if (dds_refused) {
    (*bridge)->stop();
    return app::kExitUsage;
  }
  if (again) {
    spdlog::warn("stopping: another master won the bus: starting again as a standby");
    (*bridge)->stop();
    return kRunAgain;
  }
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

}  // namespace
