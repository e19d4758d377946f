#include "app/line_check.hpp"

#include <fmt/format.h>
#include <net/if.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <map>

#include "app/arguments.hpp"
#include "app/dds_options.hpp"
#include "app/line_bridge.hpp"
#include "app/line_config_source.hpp"
#include "can/unique_fd.hpp"
#include "dds/site_profiles.hpp"

namespace lb::app {
namespace {

// Where the packaged service may write (ReadWritePaths / StateDirectory of linebridge-bus.service).
constexpr std::string_view kServiceStateDir = "/var/lib/linebridge";

// A bus that is never opened: the gateways register on it as on a real one, and nothing reaches CAN.
class StandInBus final : public can::Bus {
 public:
  explicit StandInBus(std::string uri) : uri_(std::move(uri)), fd_(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)) {}
  const std::string& uri() const override { return uri_; }
  int fd() const override { return fd_.get(); }
  Result<std::optional<can::CanFrame>> receive() override { return std::optional<can::CanFrame>{}; }
  Result<void> send(const can::CanFrame&) override { return make_error("--check sends nothing"); }
  can::BusStats stats() const override { return {}; }

 private:
  std::string uri_;
  can::UniqueFd fd_;
};

// What start-up would find on this machine that the file alone does not say.
void check_machine(const profiles::LineConfig& line, std::vector<std::string>& errors,
                   std::vector<std::string>& warnings) {
  for (const auto& bus : line.buses) {
    const std::string_view uri = bus.interface;
    if (uri.rfind("log:", 0) == 0) {
      const auto path = std::string(
          uri.substr(4, uri.find('?') == std::string_view::npos ? std::string_view::npos : uri.find('?') - 4));
      if (::access(path.c_str(), R_OK) != 0)
        errors.push_back("bus " + bus.name + ": cannot read the recording " + path);
    } else if (uri.rfind("socketcan:", 0) == 0) {
      const std::string ifname(uri.substr(10));
      if (::if_nametoindex(ifname.c_str()) == 0) {
        warnings.push_back("bus " + bus.name + ": no network interface " + ifname +
                           " on this machine: start-up here would stop (exit 1) until it exists");
      }
    }
    if (!bus.record.empty()) {
      const auto dir = std::filesystem::path(bus.record).parent_path();
      if (::access(dir.c_str(), W_OK) != 0)
        warnings.push_back("bus " + bus.name + ": cannot write to " + dir.string() + " (record:)");
      if (bus.record.rfind(kServiceStateDir, 0) != 0) {
        warnings.push_back("bus " + bus.name + ": record: " + bus.record + " is outside " +
                           std::string(kServiceStateDir) + ", the only directory the packaged service may write");
      }
    }
  }
}

// The directory the set values in force are kept in: a directory (or one start-up can create:
// its nearest existing parent is a writable directory) that this user may write. Every problem
// is reported, not only the first.
void check_state_dir(const std::string& dir, std::vector<std::string>& errors) {
  if (dir.empty()) return;  // the packaged service's $STATE_DIRECTORY serves
  const auto where = "state_dir " + dir + ": ";
  struct stat st {};
  if (::stat(dir.c_str(), &st) == 0) {
    if (!S_ISDIR(st.st_mode))
      errors.push_back(where + "not a directory (set values in force are kept there)");
    else if (::access(dir.c_str(), W_OK | X_OK) != 0)
      errors.push_back(where + "not writable by this user (" + std::strerror(errno) + ")");
    return;
  }
  if (errno != ENOENT && errno != ENOTDIR) return errors.push_back(where + std::strerror(errno));
  // Missing: start-up creates it if its nearest existing parent lets it.
  auto parent = std::filesystem::path(dir).lexically_normal();
  if (parent.is_relative()) parent = std::filesystem::current_path() / parent;
  do {
    parent = parent.parent_path();
  } while (::stat(parent.c_str(), &st) != 0 && parent != parent.root_path());
  if (!S_ISDIR(st.st_mode)) {
    errors.push_back(where + "does not exist, and " + parent.string() + " is no directory to create it in");
  } else if (::access(parent.c_str(), W_OK | X_OK) != 0) {
    errors.push_back(where + "does not exist, and this user may not create it in " + parent.string());
  }
}

// Endpoint profiles of the site's XML files that name no topic of this line: most likely a typo.
void check_profile_names(const profiles::LineConfig& line, const std::vector<ddsl::PlannedEndpoint>& planned,
                         std::vector<std::string>& warnings) {
  auto site = ddsl::load_site_profiles(line.dds.profiles_file);
  if (!site) return;
  const auto unused = [&](const std::vector<std::string>& names, bool writer, const char* what) {
    for (const auto& name : names) {
      if (name.rfind("rt/", 0) != 0 && name.rfind("rq/", 0) != 0 && name.rfind("rr/", 0) != 0)
        continue;  // not a topic name
      const bool used = std::any_of(planned.begin(), planned.end(), [&](const ddsl::PlannedEndpoint& e) {
        return e.topic == name && e.writer == writer;
      });
      if (!used)
        warnings.push_back(std::string(what) + " profile '" + name + "' names no topic the bridge " +
                           (writer ? "writes" : "reads") + " on line " + line.line);
    }
  };
  unused(site->writers, true, "data_writer");
  unused(site->readers, false, "data_reader");
}

void print_summary(const profiles::LineConfig& line, const std::vector<ddsl::PlannedEndpoint>& planned,
                   std::FILE* out) {
  const auto& dds = line.dds;
  std::string discovery = "simple discovery";
  if (!dds.discovery_servers.empty()) {
    discovery = "discovery servers";
    for (const auto& s : dds.discovery_servers) discovery += fmt::format(" {}@{}:{}", s.id, s.address, s.port);
  }
  fmt::print(out, "line {}: {} bus(es), {} device(s); DDS domain {}{}, {}{}{}\n", line.line, line.buses.size(),
             line.devices.size(), dds.domain, dds.localhost_only ? " (localhost only)" : "", discovery,
             dds.security ? ", secured (DDS Security)" : "",
             dds.profiles_file.empty() ? "" : ", profiles " + dds.profiles_file);
  if (!line.profiles_dir.empty()) fmt::print(out, "profiles_dir {}\n", line.profiles_dir);
  fmt::print(out, "status samples {} (status_publish: {})\n",
             line.status_publish == profiles::StatusPublish::per_cycle ? "per SYNC cycle" : "per burst of PDOs",
             profiles::to_string(line.status_publish));
  for (const auto& b : line.buses) {
    fmt::print(out, "bus {} on {}: {}", b.name, b.interface, profiles::to_string(b.role));
    if (profiles::masters(b.role)) {
      fmt::print(out, ", SYNC every {} ms, SDO timeout {} ms", b.sync_period.count() / 1000, b.sdo_timeout.count());
      if (b.master_node_id != 0)
        fmt::print(out, ", own heartbeat node {} every {} ms", b.master_node_id, b.master_heartbeat_period.count());
      if (b.role == profiles::BusRole::standby) {
        fmt::print(out,
                   "; negotiates with flying-master priority {} (CiA 302-2), takes over when the master's heartbeat "
                   "is silent for {} ms",
                   b.flying.priority, b.takeover_after.count());
      }
    }
    if (!b.record.empty()) fmt::print(out, ", recording to {}", b.record);
    if (b.realtime_priority != 0) fmt::print(out, ", loop at realtime priority {} (SCHED_FIFO)", b.realtime_priority);
    fmt::print(out, "\n");
    std::string mandatory;
    for (const auto& d : line.devices) {
      if (d.bus != b.name) continue;
      fmt::print(out, "  {} node {}: {} {} {} ({}), heartbeat timeout {} ms{}, pdo_config {}{}\n", d.name, d.node_id,
                 d.resolved_profile->device, d.profile, d.version, d.resolved_profile->title,
                 d.heartbeat_timeout.count(),
                 d.heartbeat_producer ? fmt::format(" (producer {} ms written to 1017h)", d.heartbeat_producer->count())
                                      : "",
                 profiles::to_string(d.pdo_config), d.mandatory ? ", mandatory" : "");
      if (d.mandatory) mandatory += (mandatory.empty() ? "" : ", ") + d.name;
    }
    if (!mandatory.empty()) {
      fmt::print(
          out,
          "  mandatory devices: {}: no device of the bus is started before they passed their boot; if one is "
          "lost or fails its boot: {}\n",
          mandatory,
          fmt::format("{} ({})", profiles::to_string(line.startup.when_mandatory_fails),
                      line.startup.when_mandatory_fails == profiles::StartupPolicy::WhenMandatoryFails::stop_others
                          ? "every other device the bridge started gets NMT stop, kept until an operator starts it"
                          : "log and diagnostics; the line runs on"));
      if (b.role == profiles::BusRole::standby) {
        fmt::print(out,
                   "  on this standby bus: nothing while it stands by; at the takeover a mandatory device heard "
                   "operational is adopted as passed, and the devices running are left running (a takeover stops "
                   "nothing); a mandatory device not heard operational gets its boot, the devices not running wait "
                   "for it, and if that boot fails: {}\n",
                   profiles::to_string(line.startup.when_mandatory_fails));
      }
    }
  }
  // One line per topic: which way the bridge uses it and with what QoS.
  std::map<std::string, std::vector<const ddsl::PlannedEndpoint*>> topics;
  for (const auto& e : planned) topics[e.topic].push_back(&e);
  fmt::print(out, "DDS topics ({}):\n", topics.size());
  for (const auto& [topic, endpoints] : topics) {
    const auto* first = endpoints.front();
    std::string how;
    for (const auto* e : endpoints) {
      const std::string h = std::string(e->writer ? "bridge writes" : "bridge reads") +
                            (e->partition.empty() ? "" : " in partition " + e->partition);
      if (how.find(h) == std::string::npos) how += (how.empty() ? "" : ", ") + h;
    }
    fmt::print(out, "  {:<44} {:<52} {} [{}]\n", topic, first->type, how, ddsl::to_string(first->kind));
  }
}

}  // namespace

int check_line(const std::string& path, const profiles::ProfileRegistry& registry, std::FILE* out, std::FILE* err) {
  auto config = load_config(path, registry);
  if (!config) return fmt::print(err, "{}\n", config.error().message), kExitUsage;
  const auto dds_options = bridge_participant_options(*config);
  auto dds = ddsl::Participant::plan(dds_options);
  if (!dds) return fmt::print(err, "{}\n", dds.error().message), kExitUsage;
  auto* planning = dds->get();

  // Every problem found is reported, each on its own line, not only the first.
  std::vector<std::string> errors;
  std::vector<std::string> warnings = config->warnings;
  check_machine(*config, errors, warnings);
  // A state directory named but unusable would start every device from zero after a restart.
  check_state_dir(config->state_dir, errors);
  // The stand-in bridge neither creates nor writes the state directory: --check changes nothing.
  auto planned_config = *config;
  planned_config.state_dir.clear();
  auto bridge = LineBridge::create(planned_config, std::move(*dds),
                                   [](const profiles::BusConfig& b) -> Result<std::unique_ptr<can::Bus>> {
                                     return std::unique_ptr<can::Bus>(std::make_unique<StandInBus>(b.interface));
                                   });
  if (!bridge) {
    for (const auto& e : errors) fmt::print(err, "error: {}\n", e);
    return fmt::print(err, "{}: {}\n", path, bridge.error().message), kExitUsage;
  }
  check_profile_names(*config, planning->planned(), warnings);
  for (const auto& n : planning->site_notes()) warnings.push_back(n);
  if (dds_options.security) {
    for (const auto& w : ddsl::security_warnings(*dds_options.security)) warnings.push_back("DDS security: " + w);
  }

  print_summary(*config, planning->planned(), out);
  for (const auto& w : warnings) fmt::print(out, "warning: {}\n", w);
  for (const auto& e : errors) fmt::print(err, "error: {}\n", e);
  if (!errors.empty()) return kExitUsage;
  fmt::print(out, "{}: ok ({} warning(s))\n", path, warnings.size());
  return kExitOk;
}

namespace {

// What makes the pair not one line with a standby (errors), and what is likely a mistake (warnings).
void compare_pair(const profiles::LineConfig& a, const profiles::LineConfig& b, std::vector<std::string>& errors,
                  std::vector<std::string>& warnings) {
  if (a.line != b.line)
    errors.push_back(fmt::format("line '{}' and line '{}': one line needs one name", a.line, b.line));
  if (a.dds.domain != b.dds.domain) {
    errors.push_back(fmt::format("DDS domain {} and {}: clients of the line would see one bridge or the other",
                                 a.dds.domain, b.dds.domain));
  }
  for (const auto& x : a.buses) {
    const auto* y = b.bus(x.name);
    if (y == nullptr) {
      errors.push_back("bus " + x.name + " is not in the peer's file");
      continue;
    }
    for (const auto* c : {&x, y}) {
      if (c->role != profiles::BusRole::standby) {
        (c->role == profiles::BusRole::master ? warnings : errors)
            .push_back(fmt::format("bus {}: role {} in {} file: give both bridges role standby (a master restarted "
                                   "beside the one that took over would master the bus too)",
                                   x.name, profiles::to_string(c->role), c == &x ? "the first" : "the peer's"));
      }
    }
    if (x.master_node_id != y->master_node_id) {
      errors.push_back(fmt::format("bus {}: master_node_id {} and {}: the devices consume one master heartbeat", x.name,
                                   x.master_node_id, y->master_node_id));
    }
    if (x.sync_period != y->sync_period) {
      errors.push_back(fmt::format("bus {}: sync_period_ms {} and {}: a takeover would change the devices' SYNC",
                                   x.name, x.sync_period.count() / 1000, y->sync_period.count() / 1000));
    }
    if (x.master_heartbeat_period != y->master_heartbeat_period) {
      warnings.push_back(fmt::format("bus {}: master_heartbeat_ms {} and {}", x.name, x.master_heartbeat_period.count(),
                                     y->master_heartbeat_period.count()));
    }
    if (x.role == profiles::BusRole::standby && y->role == profiles::BusRole::standby &&
        x.flying.priority == y->flying.priority) {
      errors.push_back(fmt::format("bus {}: both have flying-master priority {}: with one master node-ID the "
                                   "negotiation cannot tell them apart; give each its own flying_master priority",
                                   x.name, x.flying.priority));
    }
  }
  for (const auto& y : b.buses) {
    if (a.bus(y.name) == nullptr) errors.push_back("bus " + y.name + " is only in the peer's file");
  }
  for (const auto& d : a.devices) {
    const auto it = std::find_if(b.devices.begin(), b.devices.end(), [&](const auto& e) { return e.name == d.name; });
    if (it == b.devices.end()) {
      errors.push_back("device " + d.name + " is not in the peer's file");
      continue;
    }
    if (it->bus != d.bus || it->node_id != d.node_id || it->resolved_profile->key() != d.resolved_profile->key()) {
      errors.push_back(fmt::format("device {}: bus {} node {} {} here, bus {} node {} {} in the peer's file", d.name,
                                   d.bus, d.node_id, d.resolved_profile->key(), it->bus, it->node_id,
                                   it->resolved_profile->key()));
    }
    // The line's rule for its mandatory devices must not change with who masters it.
    if (it->mandatory != d.mandatory) {
      errors.push_back(fmt::format("device {}: mandatory {} here, {} in the peer's file: a takeover would change what "
                                   "the line does without it",
                                   d.name, d.mandatory, it->mandatory));
    }
    if (it->heartbeat_timeout != d.heartbeat_timeout) {
      warnings.push_back(fmt::format("device {}: heartbeat_timeout_ms {} and {}", d.name, d.heartbeat_timeout.count(),
                                     it->heartbeat_timeout.count()));
    }
  }
  for (const auto& e : b.devices) {
    if (std::none_of(a.devices.begin(), a.devices.end(), [&](const auto& d) { return d.name == e.name; }))
      errors.push_back("device " + e.name + " is only in the peer's file");
  }
  const auto any_mandatory = [](const profiles::LineConfig& c) {
    return std::any_of(c.devices.begin(), c.devices.end(), [](const auto& d) { return d.mandatory; });
  };
  if ((any_mandatory(a) || any_mandatory(b)) && a.startup.when_mandatory_fails != b.startup.when_mandatory_fails) {
    errors.push_back(fmt::format("when_mandatory_fails {} here, {} in the peer's file: a takeover would change what "
                                 "the line does when a mandatory device fails",
                                 profiles::to_string(a.startup.when_mandatory_fails),
                                 profiles::to_string(b.startup.when_mandatory_fails)));
  }
}

}  // namespace

int check_pair(const std::string& path, const std::string& peer, const profiles::ProfileRegistry& registry,
               std::FILE* out, std::FILE* err) {
  const int first = check_line(path, registry, out, err);
  const int second = check_line(peer, registry, out, err);
  if (first != kExitOk || second != kExitOk) return kExitUsage;
  const auto a = load_config(path, registry);
  const auto b = load_config(peer, registry);
  if (!a || !b) return kExitUsage;  // reported by check_line
  std::vector<std::string> errors;
  std::vector<std::string> warnings;
  compare_pair(*a, *b, errors, warnings);
  for (const auto& w : warnings) fmt::print(out, "warning: pair: {}\n", w);
  for (const auto& e : errors) fmt::print(err, "error: pair: {}\n", e);
  if (!errors.empty()) return kExitUsage;
  fmt::print(out, "{} and {}: ok as one line with a standby ({} warning(s))\n", path, peer, warnings.size());
  return kExitOk;
}

}  // namespace lb::app
