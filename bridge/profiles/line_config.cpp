#include "profiles/line_config.hpp"

#include <arpa/inet.h>
#include <algorithm>
#include <array>
#include <charconv>

#include <filesystem>
#include <map>
#include <tuple>
#include <unordered_set>

#include <fmt/format.h>

#include "base/bounded_file.hpp"
#include "can/bus.hpp"
#include "can/log_bus.hpp"
#include "canopen/cob_id.hpp"
#include "profiles/config_file.hpp"
#include "profiles/object_fields.hpp"
#include "profiles/yaml_source.hpp"

namespace lb::profiles {
namespace {

constexpr std::size_t kMaxNameLength = 64;
constexpr std::size_t kMaxBuses = 64;

// A value as an error message quotes it: long ones cut, so a hostile file cannot flood the log.
std::string shown(std::string_view text) {
  constexpr std::size_t kShown = 80;
  if (text.size() <= kShown) return "'" + std::string(text) + "'";
  return "'" + std::string(text.substr(0, kShown)) + "...' (" + std::to_string(text.size()) + " characters)";
}

// Names become parts of DDS topic names: keep them to what ROS 2 allows there. A plain loop, not
// std::regex, whose matching recurses once per character and overflows the stack on long names.
void check_name(const YamlSource& src, const YAML::Node& node, const std::string& name) {
  const auto letter = [](char c) { return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z'); };
  const bool valid = !name.empty() && name.size() <= kMaxNameLength && letter(name.front()) &&
                     std::all_of(name.begin(), name.end(),
                                 [&](char c) { return letter(c) || (c >= '0' && c <= '9') || c == '_'; });
  if (!valid) {
    src.fail(node, shown(name) + " is not a valid name (a letter, then letters, digits or '_'; at most " +
                       std::to_string(kMaxNameLength) + " characters)");
  }
}

template <class T>
T bounded(const YamlSource& src, const YAML::Node& map, std::string_view key, T fallback, std::int64_t lo,
          std::int64_t hi, std::string_view what) {
  const YAML::Node node = map[std::string(key)];
  if (!node) return fallback;
  const auto v = src.as<std::int64_t>(node, key);
  if (v < lo || v > hi) {
    src.fail(node, std::string(what) + ": " + std::string(key) + " " + std::to_string(v) + " is outside " +
                       std::to_string(lo) + ".." + std::to_string(hi));
  }
  return static_cast<T>(v);
}

double positive(const YamlSource& src, const YAML::Node& map, std::string_view key, double fallback) {
  const YAML::Node node = map[std::string(key)];
  if (!node) return fallback;
  const auto v = src.as<double>(node, key);
  if (!(v > 0)) src.fail(node, std::string(key) + " must be greater than 0");
  return v;
}

// The Fast DDS properties the file keys set: they are checked before start-up, so they cannot be
// replaced by a property that is not.
constexpr std::array kFileProperties{"dds.sec.auth.builtin.PKI-DH.identity_ca",
                                     "dds.sec.auth.builtin.PKI-DH.identity_certificate",
                                     "dds.sec.auth.builtin.PKI-DH.private_key",
                                     "dds.sec.access.builtin.Access-Permissions.permissions_ca",
                                     "dds.sec.access.builtin.Access-Permissions.governance",
                                     "dds.sec.access.builtin.Access-Permissions.permissions",
                                     "dds.sec.auth.builtin.PKI-DH.identity_crl"};

DdsSecurityConfig parse_dds_security(const YamlSource& src, const YAML::Node& n) {
  src.check_keys(n, "dds.security",
                 {"identity_ca", "certificate", "private_key", "permissions_ca", "governance", "permissions",
                  "identity_crl", "properties"});
  // Relative paths are taken from the line file's folder, wherever the bridge is started.
  const std::filesystem::path base = std::filesystem::path(src.name()).parent_path();
  const auto file = [&](const char* key) {
    const auto text = src.required<std::string>(n, key, "dds.security");
    if (text.empty()) src.fail(n[key], std::string("dds.security: ") + key + " is empty");
    if (text.rfind("file:", 0) == 0)
      src.fail(n[key], std::string("dds.security: ") + key + " is a path, not a URI: '" + text + "'");
    return std::filesystem::absolute(base / text).lexically_normal().string();
  };
  DdsSecurityConfig s;
  s.identity_ca = file("identity_ca");
  s.certificate = file("certificate");
  s.private_key = file("private_key");
  s.permissions_ca = file("permissions_ca");
  s.governance = file("governance");
  s.permissions = file("permissions");
  if (n["identity_crl"]) s.identity_crl = file("identity_crl");
  if (const YAML::Node props = n["properties"]) {
    src.expect_map(props, "dds.security.properties");
    for (const auto& kv : props) {
      const auto key = kv.first.as<std::string>();
      if (key.rfind("dds.sec.", 0) != 0)
        src.fail(kv.first, "dds.security.properties: '" + key + "' is not a dds.sec.* property");
      if (std::find(kFileProperties.begin(), kFileProperties.end(), key) != kFileProperties.end()) {
        src.fail(kv.first,
                 "dds.security.properties: '" + key + "' names a file: give it with its own dds.security key");
      }
      s.properties.emplace_back(key, src.as<std::string>(kv.second, key));
    }
  }
  return s;
}

// A path in the line file: relative ones are taken from the line file's folder.
std::string file_path(const YamlSource& src, const YAML::Node& node, std::string_view key) {
  const auto text = src.as<std::string>(node, key);
  if (text.empty()) src.fail(node, std::string(key) + ": the path is empty");
  return std::filesystem::absolute(std::filesystem::path(src.name()).parent_path() / text).lexically_normal().string();
}

std::vector<DdsDiscoveryServer> parse_discovery_servers(const YamlSource& src, const YAML::Node& list,
                                                        bool localhost_only) {
  src.expect_sequence(list, "dds.discovery_servers");
  std::vector<DdsDiscoveryServer> servers;
  for (const auto& n : list) {
    src.check_keys(n, "discovery server", {"id", "address", "port"});
    if (!n["id"]) src.fail(n, "discovery server: missing required key 'id' (fast-discovery-server -i)");
    DdsDiscoveryServer s;
    s.id = bounded<std::uint8_t>(src, n, "id", 0, 0, 255, "discovery server");
    s.address = src.required<std::string>(n, "address", "discovery server");
    in_addr addr{};
    if (::inet_pton(AF_INET, s.address.c_str(), &addr) != 1) {
      src.fail(n["address"], "discovery server: address '" + s.address + "' is not an IPv4 address");
    }
    if (localhost_only && (ntohl(addr.s_addr) >> 24) != 127) {
      src.fail(n["address"],
               "discovery server " + s.address +
                   " cannot be reached with dds.localhost_only: true (DDS stays on 127.0.0.1): set it false");
    }
    s.port = bounded<std::uint16_t>(src, n, "port", 11811, 1, 65535, "discovery server");
    for (const auto& other : servers) {
      if (other.id == s.id) src.fail(n["id"], "discovery server id " + std::to_string(s.id) + " is given twice");
    }
    servers.push_back(std::move(s));
  }
  if (servers.empty())
    src.fail(list, "dds.discovery_servers: the list is empty (leave the key out for simple discovery)");
  return servers;
}

DdsConfig parse_dds(const YamlSource& src, const YAML::Node& n) {
  src.check_keys(n, "dds",
                 {"domain", "localhost_only", "security", "profiles_file", "participant_profile", "discovery_servers",
                  "shared_memory", "max_pending_participants", "max_remote_participants"});
  DdsConfig dds;
  dds.domain = bounded<std::uint32_t>(src, n, "domain", 0, 0, 232, "dds");  // DDS/RTPS port mapping limit
  dds.localhost_only = src.optional<bool>(n, "localhost_only").value_or(true);
  if (n["security"]) dds.security = parse_dds_security(src, n["security"]);
  if (const auto f = n["profiles_file"]) {
    dds.profiles_file = file_path(src, f, "profiles_file");
    // Read as every file is (base/bounded_file.hpp): a FIFO or a device is refused, not waited on.
    if (auto text = read_bounded_file(dds.profiles_file, "DDS profiles file"); !text)
      src.fail(f, "profiles_file: cannot open " + text.error().message);
  }
  dds.participant_profile = src.optional<std::string>(n, "participant_profile").value_or("");
  if (n["participant_profile"] && dds.participant_profile.empty())
    src.fail(n["participant_profile"], "participant_profile is empty");
  dds.shared_memory = src.optional<bool>(n, "shared_memory").value_or(false);
  // At most 64: on a secured line each pending participant holds a handshake message in Fast DDS
  // 2.9.1's history of 100, and a full one aborts the process at the next handshake (the gate
  // keeps room for the authenticated ones: dds/discovery_gate.hpp).
  dds.max_pending_participants = bounded<int>(src, n, "max_pending_participants", 32, 1, 64, "dds");
  if (n["discovery_servers"])
    dds.discovery_servers = parse_discovery_servers(src, n["discovery_servers"], dds.localhost_only);
  return dds;
}

// observability: {listen: ADDRESS:PORT | off}. Numeric addresses only: a name would be resolved
// at every start, and what the page is reachable on must be what the file says.
ObservabilityConfig parse_observability(const YamlSource& src, const YAML::Node& n) {
  src.expect_map(n, "observability");
  src.check_keys(n, "observability", {"listen"});
  ObservabilityConfig o;
  const YAML::Node node = n["listen"];
  if (!node) return o;
  const auto text = src.as<std::string>(node, "listen");
  if (text == "off") {
    o.enabled = false;
    return o;
  }
  const auto bad = [&](std::string_view why) {
    src.fail(node, "observability: listen " + shown(text) + " " + std::string(why) +
                       " (ADDRESS:PORT with a numeric address, e.g. 127.0.0.1:9420 or [::1]:9420; or off)");
  };
  std::string host;
  std::string_view port_text;
  if (text.starts_with("[")) {
    const auto close = text.find("]:");
    if (close == std::string::npos) bad("is not [IPv6]:PORT");
    host = text.substr(1, close - 1);
    port_text = std::string_view(text).substr(close + 2);
    in6_addr addr6{};
    if (::inet_pton(AF_INET6, host.c_str(), &addr6) != 1) bad("does not name an IPv6 address");
  } else {
    const auto colon = text.rfind(':');
    if (colon == std::string::npos) bad("has no port");
    host = text.substr(0, colon);
    port_text = std::string_view(text).substr(colon + 1);
    in_addr addr{};
    if (::inet_pton(AF_INET, host.c_str(), &addr) != 1) bad("does not name an IPv4 address");
  }
  unsigned port = 0;
  const auto [end, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
  if (port_text.empty() || ec != std::errc{} || end != port_text.data() + port_text.size() || port < 1 ||
      port > 65535) {
    bad("has no port 1..65535");
  }
  o.address = host;
  o.port = static_cast<std::uint16_t>(port);
  return o;
}

// profiles_dir: every *.yaml in it (in name order) over the built-in profiles.
std::shared_ptr<const ProfileRegistry> load_profiles_dir(const YamlSource& src, const YAML::Node& node,
                                                         const std::string& dir, const ProfileRegistry& base,
                                                         std::vector<std::string>& warnings) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) src.fail(node, "profiles_dir: " + dir + " is not a directory");
  std::vector<std::filesystem::path> files;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    if (entry.path().extension() == ".yaml") files.push_back(entry.path());
  }
  if (ec) src.fail(node, "profiles_dir: cannot read " + dir + ": " + ec.message());
  std::sort(files.begin(), files.end());
  auto registry = std::make_shared<ProfileRegistry>(base);
  for (const auto& f : files) {
    auto p = load_profile_file(f.string());
    if (!p) throw ConfigError(p.error().message);
    if (registry->find(p->id, p->version) != nullptr) {
      warnings.push_back(f.string() + ": profile " + p->key() +
                         " replaces the one already known (built-in or an earlier file)");
    }
    registry->add(std::move(*p));
  }
  return registry;
}

// CiA 302-2 1F90h, by its sub-indexes' meanings; the priority has no default: a pair needs two.
BusConfig::FlyingMaster parse_flying_master(const YamlSource& src, const YAML::Node& bus, const std::string& what) {
  const auto n = bus["flying_master"];
  if (!n) {
    src.fail(bus["role"],
             what + ": a standby negotiates mastership (CiA 302-2): it needs flying_master: {priority: N} (0..255, "
                    "lower wins; each bridge of a pair its own)");
  }
  src.expect_map(n, what + " flying_master");
  src.check_keys(n, what + " flying_master",
                 {"priority", "detect_timeout_ms", "negotiation_delay_ms", "priority_slot_ms", "device_slot_ms",
                  "detect_cycle_ms"});
  BusConfig::FlyingMaster f;
  if (!n["priority"]) src.fail(n, what + ": flying_master needs priority (0..255, lower wins)");
  const auto where = what + " flying_master";
  f.priority = bounded<std::uint8_t>(src, n, "priority", 0, 0, 255, where);
  const auto ms = [&](const char* key, std::chrono::milliseconds fallback) {
    return std::chrono::milliseconds(bounded<int>(src, n, key, static_cast<int>(fallback.count()), 1, 65535, where));
  };
  f.detect_timeout = ms("detect_timeout_ms", f.detect_timeout);
  f.negotiation_delay = ms("negotiation_delay_ms", f.negotiation_delay);
  f.priority_slot = ms("priority_slot_ms", f.priority_slot);
  f.device_slot = ms("device_slot_ms", f.device_slot);
  f.detect_cycle = ms("detect_cycle_ms", f.detect_cycle);
  return f;
}

BusConfig parse_bus(const YamlSource& src, const YAML::Node& n) {
  src.check_keys(n, "bus",
                 {"name", "interface", "role", "sync_period_ms", "bitrate", "master_node_id", "master_heartbeat_ms",
                  "sdo_timeout_ms", "record", "other_master", "realtime_priority", "takeover_after_ms",
                  "flying_master"});
  BusConfig bus;
  bus.name = src.required<std::string>(n, "name", "bus");
  check_name(src, n["name"], bus.name);
  bus.interface = src.required<std::string>(n, "interface", "bus");
  const bool replay = bus.interface.rfind("log:", 0) == 0;
  if (auto ok = can::check_bus_uri(bus.interface); !ok) src.fail(n["interface"], ok.error().message);
  // A replayed recording cannot take frames: it only makes sense as a monitor, which is its default.
  const auto role = src.optional<std::string>(n, "role").value_or(replay ? "monitor" : "master");
  if (role != "master" && role != "monitor" && role != "standby")
    src.fail(n["role"], "role must be master, standby or monitor, not '" + role + "'");
  if (replay && role != "monitor") {
    src.fail(n["role"],
             "bus " + bus.name + ": a log: bus replays a recording and cannot transmit, so its role is monitor");
  }
  bus.record = src.optional<std::string>(n, "record").value_or("");
  if (n["record"] && bus.record.empty()) src.fail(n["record"], "record: the file path is empty");
  bus.role = role == "master" ? BusRole::master : role == "standby" ? BusRole::standby : BusRole::monitor;
  bus.sync_period = std::chrono::milliseconds(bounded<int>(src, n, "sync_period_ms", 20, 1, 10'000, "bus " + bus.name));
  bus.bitrate = bounded<std::uint32_t>(src, n, "bitrate", bus.bitrate, 10'000, 1'000'000, "bus " + bus.name);
  bus.master_node_id = bounded<std::uint8_t>(src, n, "master_node_id", 0, 0, 127, "bus " + bus.name);
  bus.master_heartbeat_period = std::chrono::milliseconds(
      bounded<int>(src, n, "master_heartbeat_ms", 1000, 1, 65535, "bus " + bus.name));
  bus.sdo_timeout = std::chrono::milliseconds(
      bounded<int>(src, n, "sdo_timeout_ms", 1000, 10, 60'000, "bus " + bus.name));
  bus.realtime_priority = bounded<int>(src, n, "realtime_priority", 0, 0, 99, "bus " + bus.name);
  if (const auto policy = src.optional<std::string>(n, "other_master")) {
    if (*policy != "yield" && *policy != "warn") {
      src.fail(n["other_master"],
               "other_master must be yield (transmit nothing while another master is heard) or warn, not '" + *policy +
                   "'");
    }
    if (bus.role == BusRole::monitor)
      src.fail(n["other_master"], "bus " + bus.name + ": other_master is for the master and standby roles");
    bus.yield_to_other_master = *policy == "yield";
  }
  if (bus.master_node_id != 0 && bus.role == BusRole::monitor) {
    src.fail(n["master_node_id"], "bus " + bus.name + ": a monitor bus never transmits, so it has no master_node_id");
  }
  if (bus.role == BusRole::standby) {
    if (bus.master_node_id == 0) {
      src.fail(n["role"], "bus " + bus.name +
                              ": a standby watches the master's heartbeat and takes it over: it needs master_node_id "
                              "(the same in both bridges' line files)");
    }
    // Default: two of the master's heartbeat periods and a half (a heartbeat late by a period is no loss).
    bus.takeover_after = std::chrono::milliseconds(
        bounded<int>(src, n, "takeover_after_ms", static_cast<int>(bus.master_heartbeat_period.count() * 5 / 2), 10,
                     60'000, "bus " + bus.name));
    if (bus.takeover_after <= bus.master_heartbeat_period) {
      src.fail(n["takeover_after_ms"],
               fmt::format("bus {}: takeover_after_ms {} must be longer than the master's "
                           "heartbeat period master_heartbeat_ms {}",
                           bus.name, bus.takeover_after.count(), bus.master_heartbeat_period.count()));
    }
    bus.flying = parse_flying_master(src, n, "bus " + bus.name);
  } else {
    if (n["takeover_after_ms"])
      src.fail(n["takeover_after_ms"], "bus " + bus.name + ": takeover_after_ms is for the standby role");
    if (n["flying_master"]) {
      src.fail(n["flying_master"],
               "bus " + bus.name + ": flying_master is for the standby role (a master bus does not negotiate)");
    }
  }
  return bus;
}

Identity parse_identity(const YamlSource& src, const YAML::Node& n, std::string_view what) {
  src.expect_map(n, what);
  src.check_keys(n, what, {"device_type", "vendor_id", "product_code", "revision", "serial_number"});
  Identity id;
  id.device_type = src.optional<std::uint32_t>(n, "device_type");
  id.vendor_id = src.optional<std::uint32_t>(n, "vendor_id");
  id.product_code = src.optional<std::uint32_t>(n, "product_code");
  id.revision = src.optional<std::uint32_t>(n, "revision");
  id.serial_number = src.optional<std::uint32_t>(n, "serial_number");
  return id;
}

std::vector<canopen::PdoEntry> parse_mapping_entries(const YamlSource& src, const YAML::Node& m) {
  src.expect_sequence(m, "mapping");
  std::vector<canopen::PdoEntry> entries;
  for (const auto& e : m) entries.push_back(canopen::PdoEntry::from_u32(src.as<std::uint32_t>(e, "mapping")));
  if (auto checked = canopen::PdoMapping::create(entries); !checked) src.fail(m, checked.error().message);
  return entries;
}

// simulation.pdos: {<name>: {cob_id, transmission_type, inhibit_time_100us, event_timer_ms, mapping}}
std::vector<SimulatedPdo> parse_simulated_pdos(const YamlSource& src, const YAML::Node& n, const Profile& profile) {
  src.expect_map(n, "simulation pdos");
  std::vector<SimulatedPdo> pdos;
  for (const auto& kv : n) {
    SimulatedPdo p;
    p.name = src.as<std::string>(kv.first, "pdo");
    if (profile.pdo(p.name) == nullptr)
      src.fail(kv.first, "simulation pdos: profile " + profile.key() + " has no PDO '" + p.name + "'");
    const YAML::Node& o = kv.second;
    src.check_keys(o, "simulation pdo",
                   {"cob_id", "transmission_type", "inhibit_time_100us", "event_timer_ms", "mapping"});
    p.cob_id = src.optional<std::uint32_t>(o, "cob_id");
    if (o["transmission_type"])
      p.transmission_type = bounded<std::uint8_t>(src, o, "transmission_type", 0, 0, 255, "simulation pdo");
    if (o["inhibit_time_100us"])
      p.inhibit_time_100us = bounded<std::uint16_t>(src, o, "inhibit_time_100us", 0, 0, 65535, "simulation pdo");
    if (o["event_timer_ms"])
      p.event_timer_ms = bounded<std::uint16_t>(src, o, "event_timer_ms", 0, 0, 65535, "simulation pdo");
    if (o["mapping"]) p.mapping = parse_mapping_entries(src, o["mapping"]);
    pdos.push_back(std::move(p));
  }
  return pdos;
}

SimulationConfig parse_simulation(const YamlSource& src, const YAML::Node& n, const Profile& profile) {
  src.check_keys(n, "simulation",
                 {"max_speed_m_per_min", "acceleration_m_per_min_s", "scaling_pulses_per_m", "heartbeat_period_ms",
                  "controller_values", "identity", "pdos", "ignore_writes", "pre_defined_error_field",
                  "boot_up_after_nmt_reset", "reset_time_ms"});
  SimulationConfig sim;
  sim.max_speed_m_per_min = positive(src, n, "max_speed_m_per_min", sim.max_speed_m_per_min);
  sim.acceleration_m_per_min_s = positive(src, n, "acceleration_m_per_min_s", sim.acceleration_m_per_min_s);
  sim.scaling_pulses_per_m = bounded<std::uint32_t>(src, n, "scaling_pulses_per_m", sim.scaling_pulses_per_m, 1,
                                                    100'000'000, "simulation");
  // 0: the device sends no heartbeat until a master writes 1017h.
  sim.heartbeat_period = std::chrono::milliseconds(
      bounded<int>(src, n, "heartbeat_period_ms", 100, 0, 65535, "simulation"));
  sim.pre_defined_error_field = src.optional<bool>(n, "pre_defined_error_field").value_or(true);
  sim.boot_up_after_nmt_reset = src.optional<bool>(n, "boot_up_after_nmt_reset").value_or(true);
  sim.reset_time = std::chrono::milliseconds(bounded<int>(src, n, "reset_time_ms", 0, 0, 60000, "simulation"));
  if (n["identity"]) sim.identity = parse_identity(src, n["identity"], "simulation identity");
  if (n["pdos"]) sim.pdos = parse_simulated_pdos(src, n["pdos"], profile);
  if (const auto ignore = n["ignore_writes"]) {
    src.expect_sequence(ignore, "ignore_writes");
    for (const auto& w : ignore) {
      src.check_keys(w, "ignore_writes entry", {"index", "sub"});
      if (!w["index"]) src.fail(w, "ignore_writes entry: missing required key 'index'");
      const auto index = bounded<std::uint32_t>(src, w, "index", 0, 0x1000, 0xFFFF, "ignore_writes");
      const auto sub = bounded<std::uint32_t>(src, w, "sub", 0, 0, 255, "ignore_writes");
      sim.ignore_writes.push_back(index << 8 | sub);
    }
  }
  if (const auto values = n["controller_values"]) {
    src.expect_map(values, "controller_values");
    for (const auto& kv : values) {
      const auto name = kv.first.as<std::string>();
      const ObjectDef* obj = profile.object(name);
      if (obj == nullptr)
        src.fail(kv.first, "controller_values: profile " + profile.key() + " has no object '" + name + "'");
      const auto raw = src.as<std::uint64_t>(kv.second, name);
      if (raw > canopen::type_max(obj->type))
        src.fail(kv.second, "controller_values: " + name + " does not fit its type");
      sim.controller_values.emplace_back(name, raw);
    }
  }
  return sim;
}

// configure: [{object: name, value: v} | {index: i, sub: s, type: T, value: v}, ...]; the value is
// raw (what the SDO carries), checked against the type and, for profile objects, its access.
std::vector<SdoWrite> parse_configure(const YamlSource& src, const YAML::Node& list, const Profile& profile,
                                      const std::string& device) {
  src.expect_sequence(list, "configure");
  std::vector<SdoWrite> writes;
  for (const auto& w : list) {
    src.check_keys(w, "configure entry", {"object", "index", "sub", "type", "value", "verify"});
    SdoWrite write;
    if (w["object"]) {
      const auto name = src.as<std::string>(w["object"], "object");
      const ObjectDef* obj = profile.object(name);
      if (obj == nullptr)
        src.fail(w["object"], "device " + device + ": profile " + profile.key() + " has no object '" + name + "'");
      if (!obj->writable())
        src.fail(w["object"],
                 "device " + device + ": " + name + " is " + std::string(to_string(obj->access)) + ", not writable");
      write.index = obj->index;
      write.sub = obj->sub;
      write.type = obj->type;
      write.verify = obj->readable();
    } else {
      write.index = bounded<std::uint16_t>(src, w, "index", 0, 0x1000, 0xFFFF, "configure entry");
      if (!w["index"]) src.fail(w, "configure entry: give either object or index, sub and type");
      write.sub = bounded<std::uint8_t>(src, w, "sub", 0, 0, 255, "configure entry");
      const auto type_text = src.required<std::string>(w, "type", "configure entry");
      const auto type = canopen::parse_data_type(type_text);
      if (!type) src.fail(w["type"], "unknown data type '" + type_text + "'");
      write.type = *type;
    }
    const YAML::Node v = w["value"];
    if (!v) src.fail(w, "configure entry: missing required key 'value'");
    write.text = v.IsScalar() ? v.Scalar() : "<non-scalar>";
    if (write.type == canopen::DataType::visible_string) {
      write.value = src.as<std::string>(v, "value");
    } else if (write.type == canopen::DataType::real32 || write.type == canopen::DataType::real64) {
      write.value = src.as<double>(v, "value");
    } else if (canopen::is_signed_integer(write.type)) {
      write.value = src.as<std::int64_t>(v, "value");
    } else if (canopen::is_unsigned_integer(write.type)) {
      write.value = src.as<std::uint64_t>(v, "value");
    } else {
      src.fail(w, "configure entry: " + std::string(canopen::to_string(write.type)) + " values are not supported here");
    }
    if (auto bytes = canopen::encode(write.type, write.value); !bytes)
      src.fail(v, "configure entry: " + bytes.error().message);
    if (const auto verify = src.optional<bool>(w, "verify")) write.verify = *verify;
    writes.push_back(std::move(write));
  }
  return writes;
}

// pdos: {<name>: {cob_id, transmission_type, inhibit_time_100us, event_timer_ms, mapping}}: any
// key not given keeps the profile's default. cob_id is the full CiA 301 entry (bit 31 disables the
// PDO, bit 29 makes the identifier 29-bit), node-ID included.
std::vector<DevicePdo> resolve_pdos(const YamlSource& src, const YAML::Node* overrides, const Profile& profile,
                                    std::uint8_t node_id, const std::string& device) {
  std::vector<DevicePdo> pdos = default_pdos(profile, node_id);
  if (overrides == nullptr) return pdos;
  src.expect_map(*overrides, "pdos");
  for (const auto& kv : *overrides) {
    const auto name = kv.first.as<std::string>();
    auto it = std::find_if(pdos.begin(), pdos.end(), [&](const DevicePdo& p) { return p.name == name; });
    if (it == pdos.end()) {
      std::string known;
      for (const auto& p : pdos) known += (known.empty() ? "" : ", ") + p.name;
      src.fail(kv.first,
               "device " + device + ": profile " + profile.key() + " has no PDO '" + name + "' (" + known + ")");
    }
    const YAML::Node& o = kv.second;
    src.check_keys(o, "pdo override",
                   {"cob_id", "transmission_type", "inhibit_time_100us", "event_timer_ms", "mapping"});
    if (o["cob_id"]) {
      const auto entry = src.as<std::uint32_t>(o["cob_id"], "cob_id");
      it->validity_given = true;
      it->enabled = (entry & 0x8000'0000U) == 0;
      it->extended = (entry & 0x2000'0000U) != 0;
      it->can_id = entry & (it->extended ? 0x1FFF'FFFFU : 0x7FFU);
      if (!it->extended && (entry & 0x1FFF'F800U) != 0) {
        src.fail(o["cob_id"], "cob_id: an 11-bit identifier (bit 29 clear) must be below 800h");
      }
    }
    it->transmission_type = bounded<std::uint8_t>(src, o, "transmission_type", it->transmission_type, 0, 255,
                                                  "pdo " + name);
    if (it->transmission_type > 240 && it->transmission_type < 252) {
      src.fail(o["transmission_type"],
               "transmission_type " + std::to_string(it->transmission_type) + " is reserved (CiA 301)");
    }
    if (it->direction == PdoDirection::rx && it->transmission_type > 240 && it->transmission_type < 254) {
      src.fail(o["transmission_type"],
               "transmission_type " + std::to_string(it->transmission_type) +
                   " is for TPDOs only: an RPDO is 0..240 (synchronous) or 254/255 (event-driven)");
    }
    it->inhibit = std::chrono::microseconds(100 *
                                            bounded<int>(src, o, "inhibit_time_100us", 0, 0, 65535, "pdo " + name));
    it->event_timer = std::chrono::milliseconds(bounded<int>(src, o, "event_timer_ms", 0, 0, 65535, "pdo " + name));
    if (const auto m = o["mapping"]) {
      src.expect_sequence(m, "mapping");
      it->mapping.clear();
      for (const auto& e : m) {
        const auto entry = canopen::PdoEntry::from_u32(src.as<std::uint32_t>(e, "mapping"));
        if (!entry.is_dummy()) {
          const ObjectDef* obj = profile.object(entry.index, entry.sub);
          if (obj == nullptr)
            src.fail(e, "mapping entry names an object profile " + profile.key() + " does not define");
          if (canopen::bit_size(obj->type) != entry.bits)
            src.fail(e, "mapping entry length differs from " + obj->name + "'s type");
          if (it->direction == PdoDirection::tx && !obj->readable())
            src.fail(e, "a TPDO cannot carry " + obj->name + ", which is write-only");
          if (it->direction == PdoDirection::rx && !obj->writable()) {
            src.fail(e, "an RPDO cannot carry " + obj->name + ", which is " + std::string(to_string(obj->access)));
          }
        } else if (it->direction == PdoDirection::tx) {
          src.fail(e, "dummy entries (0001h..0007h) skip bits of a received PDO: a TPDO cannot carry them (CiA 301)");
        }
        it->mapping.push_back(entry);
      }
      if (auto checked = canopen::PdoMapping::create(it->mapping); !checked) src.fail(m, checked.error().message);
    }
  }
  return pdos;
}

// CiA 301 lets a master change a TPDO's inhibit time only while the PDO is not valid; where the
// profile fixes the COB-ID (saw 3.1: const) the PDO is valid for good, so the boot can never write
// it: a line value other than the profile's default is a boot error J on every device that still
// has the default. Said at --check, before the line runs.
void warn_fixed_inhibit_times(const YamlSource& src, const YAML::Node& overrides, const DeviceConfig& dev,
                              std::vector<std::string>& warnings) {
  for (const auto& pdo : dev.pdos) {
    const PdoDef* def = dev.bridge_profile().pdo(pdo.name);
    if (def == nullptr || def->direction != PdoDirection::tx || def->rules.cob_id != PdoAccess::fixed) continue;
    const YAML::Node o = overrides[pdo.name];
    if (!o || !o.IsMap() || !o["inhibit_time_100us"] || pdo.inhibit.count() == 0) continue;
    warnings.push_back(
        src.where(o["inhibit_time_100us"]) +
        fmt::format(": device {}: {} inhibit_time_100us {}: profile {} makes this PDO's COB-ID const, so "
                    "it cannot be made not valid and CiA 301 forbids writing its inhibit time; unless the "
                    "device already has that value (the profile's default is 0) its boot fails with J "
                    "(pdo_config: adopt takes the device's value)",
                    dev.name, pdo.name, pdo.inhibit.count() / 100, dev.bridge_profile().key()));
  }
}

// What the devices so far use: the checks against all earlier devices stay linear in their number.
struct Taken {
  std::unordered_set<std::string> device_names;
  std::map<std::pair<std::string, std::uint8_t>, std::string> node_ids;         // (bus, node-ID) -> device
  std::map<std::tuple<std::string, bool, std::uint32_t>, std::string> pdo_ids;  // (bus, 29-bit, identifier) -> PDO
};

// Where a PDO's identifier comes from: its cob_id override, or else the node-ID it is derived from.
YAML::Node identifier_node(const YAML::Node& device, const std::string& pdo) {
  if (const YAML::Node overrides = device["pdos"]; overrides && overrides.IsMap()) {
    if (const YAML::Node o = overrides[pdo]; o && o.IsMap() && o["cob_id"]) return o["cob_id"];
  }
  return device["node_id"];
}

// No PDO on an identifier CiA 301 keeps for another service (an RPDO on 000h would be taken for
// NMT commands, a TPDO on 080h for SYNC), whether it comes from an override or from the profile's
// default (profile files are input too), valid or not (it may be made valid later). And one
// identifier carries one PDO on a bus: two devices (or two PDOs of one) sending or expecting
// different data under one identifier would each decode the other's frames.
void claim_pdo_identifiers(const YamlSource& src, const YAML::Node& n, const DeviceConfig& dev, Taken& taken) {
  for (const auto& pdo : dev.pdos) {
    const auto who = "pdo " + pdo.name + " of device " + dev.name;
    if (const auto use = canopen::cob::restricted_use(pdo.can_id); !pdo.extended && !use.empty()) {
      src.fail(identifier_node(n, pdo.name),
               fmt::format("{}: identifier {:03X}h is {}: CiA 301 restricts it, no PDO may use it", who, pdo.can_id,
                           use));
    }
    if (!pdo.enabled && pdo.validity_given) continue;  // never on the bus
    const auto [it, added] = taken.pdo_ids.try_emplace({dev.bus, pdo.extended, pdo.can_id}, who);
    if (!added) {
      src.fail(identifier_node(n, pdo.name), fmt::format("{}: identifier {:0{}X}h is already used by {} on bus {}", who,
                                                         pdo.can_id, pdo.extended ? 8 : 3, it->second, dev.bus));
    }
  }
}

StartupPolicy parse_startup(const YamlSource& src, const YAML::Node& n) {
  src.expect_map(n, "startup");
  src.check_keys(n, "startup",
                 {"set_values_max_age_s", "after_power_loss", "restart_after_power_loss", "when_mandatory_fails",
                  "pdo_change_when_running"});
  StartupPolicy p;
  p.set_values_max_age = std::chrono::seconds(
      bounded<int>(src, n, "set_values_max_age_s", 3600, 0, 30 * 86400, "startup"));
  if (const auto v = src.optional<std::string>(n, "after_power_loss")) {
    if (*v == "non_enabling")
      p.after_power_loss = StartupPolicy::AfterPowerLoss::non_enabling;
    else if (*v == "nothing")
      p.after_power_loss = StartupPolicy::AfterPowerLoss::nothing;
    else
      src.fail(n["after_power_loss"],
               "after_power_loss must be non_enabling (speeds, lengths and modes come back) or nothing, not '" + *v +
                   "'");
  }
  if (const auto v = src.optional<std::string>(n, "restart_after_power_loss")) {
    if (*v == "never")
      p.restart_after_power_loss = StartupPolicy::Restart::never;
    else if (*v == "allowed")
      p.restart_after_power_loss = StartupPolicy::Restart::allowed;
    else
      src.fail(n["restart_after_power_loss"], "restart_after_power_loss must be never or allowed, not '" + *v + "'");
  }
  if (const auto v = src.optional<std::string>(n, "when_mandatory_fails")) {
    if (*v == "stop_others")
      p.when_mandatory_fails = StartupPolicy::WhenMandatoryFails::stop_others;
    else if (*v == "report_only")
      p.when_mandatory_fails = StartupPolicy::WhenMandatoryFails::report_only;
    else
      src.fail(n["when_mandatory_fails"], "when_mandatory_fails must be stop_others (every other device the bridge "
                                          "started is stopped until an operator starts it) or report_only, not '" +
                                              *v + "'");
  }
  if (const auto v = src.optional<std::string>(n, "pdo_change_when_running")) {
    using canopen::PdoChangeWhenRunning;
    if (*v == "pre_operational")
      p.pdo_change_when_running = PdoChangeWhenRunning::pre_operational;
    else if (*v == "keep_running")
      p.pdo_change_when_running = PdoChangeWhenRunning::keep_running;
    else
      src.fail(n["pdo_change_when_running"],
               "pdo_change_when_running must be pre_operational (a running device is put in "
               "pre-operational to write its PDOs) or keep_running, not '" +
                   *v + "'");
  }
  return p;
}

DeviceConfig parse_device(const YamlSource& src, const YAML::Node& n, const LineConfig& line,
                          const ProfileRegistry& registry, std::vector<std::string>& warnings, Taken& taken) {
  src.check_keys(n, "device",
                 {"name", "bus", "node_id", "profile", "version", "heartbeat_timeout_ms", "configure", "boot_retry_ms",
                  "pdos", "simulation", "identity", "pdo_config", "on_state_unknown", "heartbeat_producer_ms",
                  "objects", "starts_itself", "mandatory"});
  DeviceConfig dev;
  dev.name = src.required<std::string>(n, "name", "device");
  check_name(src, n["name"], dev.name);
  // rt/<line>/bridge/... and <line>/bridge/<service> are the bridge's own (diagnostics, the
  // line-wide services, lb::ddsl::kBridgeNamespace): a device of that name would meet them.
  if (dev.name == "bridge")
    src.fail(n["name"], "device name 'bridge' is reserved for the bridge's own topics and services");
  if (!taken.device_names.insert(dev.name).second) src.fail(n["name"], "device name '" + dev.name + "' is used twice");
  dev.bus = src.required<std::string>(n, "bus", "device " + dev.name);
  if (line.bus(dev.bus) == nullptr) src.fail(n["bus"], "device " + dev.name + ": no bus named '" + dev.bus + "'");
  if (!n["node_id"]) src.fail(n, "device " + dev.name + ": missing required key 'node_id'");
  dev.node_id = bounded<std::uint8_t>(src, n, "node_id", 0, 1, 127, "device " + dev.name);
  if (line.bus(dev.bus)->master_node_id == dev.node_id) {
    src.fail(n["node_id"], "device " + dev.name + ": node-ID " + std::to_string(dev.node_id) +
                               " is the bridge's own (master_node_id of bus " + dev.bus + ")");
  }
  if (const auto [other, added] = taken.node_ids.try_emplace({dev.bus, dev.node_id}, dev.name); !added) {
    src.fail(n["node_id"], "device " + dev.name + ": node-ID " + std::to_string(dev.node_id) + " is already used by " +
                               other->second + " on bus " + dev.bus);
  }
  dev.profile = src.required<std::string>(n, "profile", "device " + dev.name);
  dev.version = src.required<std::string>(n, "version", "device " + dev.name);
  dev.resolved_profile = registry.find(dev.profile, dev.version);
  if (dev.resolved_profile == nullptr) {
    std::string known;
    for (const auto& k : registry.keys()) known += (known.empty() ? "" : ", ") + k;
    src.fail(n["profile"], "device " + dev.name + ": unknown profile " + dev.profile + " version " + dev.version +
                               " (known: " + known + ")");
  }
  if (const auto objects = n["objects"]) {
    // The device's own objects the bridge is to know by name (a manufacturer-specific one mapped
    // into a PDO): the bridge decodes by the profile with them. The simulator keeps the profile.
    src.expect_sequence(objects, "objects");
    Profile extended = *dev.resolved_profile;
    for (const auto& o : objects) {
      src.check_keys(o, "object",
                     {"index", "sub", "name", "type", "access", "unit", "scale", "eng_unit", "min", "max", "values",
                      "special_values"});
      ObjectDef def = parse_object_fields(src, o, "device " + dev.name + " object");
      if (extended.object(def.name) != nullptr)
        src.fail(o["name"], "object name '" + def.name + "' is already the profile's or used twice");
      if (extended.object(def.index, def.sub) != nullptr) {
        src.fail(o["index"], "device " + dev.name + ": the object at this index and sub is already " +
                                 extended.object(def.index, def.sub)->name);
      }
      extended.objects.push_back(std::move(def));
    }
    dev.profile_with_objects = std::make_shared<const Profile>(std::move(extended));
  }
  dev.heartbeat_timeout = std::chrono::milliseconds(
      bounded<int>(src, n, "heartbeat_timeout_ms", 500, 1, 65535, "device " + dev.name));
  dev.boot_retry = std::chrono::milliseconds(
      bounded<int>(src, n, "boot_retry_ms", 5000, 100, 600'000, "device " + dev.name));
  if (n["configure"]) dev.configure = parse_configure(src, n["configure"], dev.bridge_profile(), dev.name);
  const YAML::Node pdo_overrides = n["pdos"];
  dev.pdos = resolve_pdos(src, pdo_overrides ? &pdo_overrides : nullptr, dev.bridge_profile(), dev.node_id, dev.name);
  claim_pdo_identifiers(src, n, dev, taken);
  if (n["simulation"]) dev.simulation = parse_simulation(src, n["simulation"], *dev.resolved_profile);
  if (n["identity"]) dev.identity = parse_identity(src, n["identity"], "identity");
  if (const auto mode = src.optional<std::string>(n, "pdo_config")) {
    if (*mode == "configure")
      dev.pdo_config = PdoConfigMode::configure;
    else if (*mode == "adopt")
      dev.pdo_config = PdoConfigMode::adopt;
    else
      src.fail(
          n["pdo_config"],
          "pdo_config must be configure (make the device match the line) or adopt (take the device's PDOs), not '" +
              *mode + "'");
  }
  if (dev.pdo_config == PdoConfigMode::configure && pdo_overrides) {
    warn_fixed_inhibit_times(src, pdo_overrides, dev, warnings);
  }
  if (const auto action = src.optional<std::string>(n, "on_state_unknown")) {
    if (*action == "reboot")
      dev.on_state_unknown = StateUnknownAction::reboot;
    else if (*action == "reset_node")
      dev.on_state_unknown = StateUnknownAction::reset_node;
    else
      src.fail(n["on_state_unknown"], "on_state_unknown must be reboot or reset_node, not '" + *action + "'");
  }
  dev.starts_itself = src.optional<bool>(n, "starts_itself").value_or(false);
  dev.mandatory = src.optional<bool>(n, "mandatory").value_or(false);
  // Only a master starts and stops devices: on a monitor bus the key would promise what nobody does.
  if (dev.mandatory && line.bus(dev.bus)->role == BusRole::monitor) {
    src.fail(n["mandatory"], "device " + dev.name + ": mandatory is for a master or standby bus: bus " + dev.bus +
                                 " is in the monitor role, where the bridge never starts or stops a device");
  }
  if (n["heartbeat_producer_ms"]) {
    const auto producer = bounded<int>(src, n, "heartbeat_producer_ms", 0, 1, 65535, "device " + dev.name);
    dev.heartbeat_producer = std::chrono::milliseconds(producer);
    // A consumer time at or below the producer time reports the device lost between two beats.
    if (dev.heartbeat_timeout.count() <= producer) {
      src.fail(n["heartbeat_producer_ms"],
               "device " + dev.name + ": heartbeat_producer_ms " + std::to_string(producer) +
                   " must be below heartbeat_timeout_ms " + std::to_string(dev.heartbeat_timeout.count()) +
                   " (CiA 302: the consumer time needs a margin, e.g. 1.5 x the producer time)");
    }
    if (2 * dev.heartbeat_timeout.count() < 3 * producer) {
      warnings.push_back(src.where(n["heartbeat_timeout_ms"] ? n["heartbeat_timeout_ms"] : n["heartbeat_producer_ms"]) +
                         ": device " + dev.name + ": heartbeat_timeout_ms " +
                         std::to_string(dev.heartbeat_timeout.count()) + " is less than 1.5 x heartbeat_producer_ms " +
                         std::to_string(producer) + ": one late heartbeat reports the device lost");
    }
  }
  return dev;
}

// The file a path names, as far as it can be told before the file exists.
std::filesystem::path file_identity(const std::string& path) {
  std::error_code ec;
  auto p = std::filesystem::weakly_canonical(std::filesystem::absolute(path, ec), ec);
  return ec ? std::filesystem::path(path).lexically_normal() : p;
}

// A recording must not be a file a log: bus replays (it would read what it writes and grow without
// bound) nor the recording of another bus (two writers interleave their lines).
void check_recordings(const YamlSource& src, const YAML::Node& nodes, const std::vector<BusConfig>& buses) {
  std::map<std::filesystem::path, std::string> files;  // replayed or recorded file -> its bus and use
  for (const auto& bus : buses) {
    if (bus.interface.rfind("log:", 0) != 0) continue;
    if (auto spec = can::LogBus::parse_spec(std::string_view(bus.interface).substr(4))) {
      files.emplace(file_identity(spec->path), "bus " + bus.name + " replays it");
    }
  }
  for (std::size_t i = 0; i < buses.size(); ++i) {
    if (buses[i].record.empty()) continue;
    const auto [it, added] = files.try_emplace(file_identity(buses[i].record),
                                               "bus " + buses[i].name + " records into it");
    if (!added) {
      src.fail(nodes[i]["record"], "bus " + buses[i].name + ": record: " + shown(buses[i].record) +
                                       " cannot be recorded into: " + it->second);
    }
  }
}

}  // namespace

std::vector<DevicePdo> default_pdos(const Profile& profile, std::uint8_t node_id) {
  std::vector<DevicePdo> pdos;
  for (const auto& def : profile.pdos) {
    DevicePdo pdo;
    pdo.name = def.name;
    pdo.direction = def.direction;
    pdo.can_id = def.cob_id(node_id);
    pdo.enabled = def.validity != PdoValidity::not_valid;
    pdo.validity_given = def.validity != PdoValidity::either;
    pdo.transmission_type = def.transmission_type;
    pdo.mapping = def.mapping;
    pdos.push_back(std::move(pdo));
  }
  return pdos;
}

std::string_view to_string(BusRole role) {
  switch (role) {
    case BusRole::master: return "master";
    case BusRole::standby: return "standby";
    case BusRole::monitor: break;
  }
  return "monitor";
}
std::string_view to_string(StatusPublish p) { return p == StatusPublish::per_cycle ? "per_cycle" : "per_frame"; }
std::string_view to_string(PdoConfigMode mode) { return mode == PdoConfigMode::configure ? "configure" : "adopt"; }
std::string_view to_string(StartupPolicy::WhenMandatoryFails policy) {
  return policy == StartupPolicy::WhenMandatoryFails::stop_others ? "stop_others" : "report_only";
}
std::string_view to_string(StateUnknownAction action) {
  return action == StateUnknownAction::reboot ? "reboot" : "reset_node";
}

const BusConfig* LineConfig::bus(std::string_view name) const {
  for (const auto& b : buses) {
    if (b.name == name) return &b;
  }
  return nullptr;
}

const DeviceConfig* LineConfig::device(std::string_view name) const {
  for (const auto& d : devices) {
    if (d.name == name) return &d;
  }
  return nullptr;
}

namespace {

// Every CiA 420 device answers 01A4h in 1000h: without identity: (vendor_id or product_code) a
// puller plugged in at the saw's node-ID passes the boot and gets the saw's control word. The
// master buses' devices that only 1000h bits 0..15 tell apart are named.
void warn_identity_by_profile_number_alone(LineConfig& cfg) {
  for (const auto& bus : cfg.buses) {
    if (!masters(bus.role)) continue;
    std::map<std::uint32_t, std::vector<const DeviceConfig*>> by_number;
    for (const auto& d : cfg.devices) {
      if (d.bus == bus.name) by_number[d.resolved_profile->device_type & 0xFFFF].push_back(&d);
    }
    for (const auto& [number, devices] : by_number) {
      if (devices.size() < 2) continue;
      std::vector<std::string> bare;
      for (const auto* d : devices) {
        if (!d->identity.vendor_id && !d->identity.product_code && !d->identity.serial_number) bare.push_back(d->name);
      }
      if (bare.empty()) continue;
      std::string names;
      for (const auto& n : bare) names += (names.empty() ? "" : ", ") + n;
      cfg.warnings.push_back(fmt::format("bus {}: {} ha{} no identity: (vendor_id, product_code) and {} told apart "
                                         "from the other CiA {} device(s) of the bus "
                                         "by 1000h bits 0..15 alone: any CiA {} device at {} node-ID is taken for {} "
                                         "(`linebridge-cli identity <device>` "
                                         "prints the lines to add)",
                                         bus.name, names, bare.size() == 1 ? "s" : "ve",
                                         bare.size() == 1 ? "is" : "are", number, number,
                                         bare.size() == 1 ? "its" : "their", bare.size() == 1 ? "it" : "them"));
    }
  }
}

}  // namespace

Result<LineConfig> parse_line_config(const std::string& yaml_text, const std::string& source,
                                     const ProfileRegistry& registry) {
  const YamlSource src(source);
  try {
    const YAML::Node root = src.parse(yaml_text);
    if (!root.IsMap()) src.fail(root, "a line configuration must be a mapping with line, buses and devices");
    src.check_keys(root, "line configuration",
                   {"line", "dds", "profiles_dir", "buses", "devices", "state_dir", "restore_set_values", "startup",
                    "observability", "status_publish"});
    LineConfig cfg;
    cfg.line = src.required<std::string>(root, "line", "line configuration");
    check_name(src, root["line"], cfg.line);
    if (root["state_dir"]) {
      cfg.state_dir = src.as<std::string>(root["state_dir"], "state_dir");
      if (cfg.state_dir.empty()) src.fail(root["state_dir"], "state_dir: the directory is empty");
    }
    cfg.restore_set_values = src.optional<bool>(root, "restore_set_values").value_or(true);
    if (const auto sp = root["status_publish"]) {
      const auto text = src.as<std::string>(sp, "status_publish");
      if (text == "per_frame") {
        cfg.status_publish = StatusPublish::per_frame;
      } else if (text != "per_cycle") {
        src.fail(sp, "status_publish: '" + text +
                         "' is neither per_cycle (a device's status once per SYNC cycle, the "
                         "default) nor per_frame (per burst of PDOs as they are read)");
      }
    }
    if (const auto startup = root["startup"]) {
      cfg.startup = parse_startup(src, startup);
      if (cfg.startup.restart_after_power_loss == StartupPolicy::Restart::allowed) {
        cfg.warnings.push_back(src.where(startup["restart_after_power_loss"]) +
                               ": restart_after_power_loss: allowed: after a power loss or a reset the bridge switches "
                               "enabling levels (saw program on, extruder running) back on by itself; IEC 60204-1 7.5 "
                               "allows that only where it cannot cause a hazard");
      }
    }
    if (const auto obs = root["observability"]) cfg.observability = parse_observability(src, obs);
    if (root["dds"]) {
      cfg.dds = parse_dds(src, root["dds"]);
      // Older line files bound every remote participant so (the DDS process ended past it).
      if (const auto old = root["dds"]["max_remote_participants"]) {
        cfg.warnings.push_back(src.where(old) +
                               ": dds.max_remote_participants is no longer used and is ignored: the DDS process no "
                               "longer ends past a number of participants; what unauthenticated participants may make "
                               "it hold is bounded by dds.max_pending_participants (docs/site-dds.md)");
      }
    }
    if (cfg.dds.security && !cfg.dds.discovery_servers.empty()) {
      // Measured with Fast DDS 2.9.1: through an unsecured fast-discovery-server secured
      // participants fail endpoint matching; a secured server's GUID prefix is replaced by one
      // derived from its certificate, so clients never find the prefix they were given.
      cfg.warnings.push_back(
          src.where(root["dds"]["discovery_servers"]) +
          ": dds.security with discovery servers: with Fast DDS 2.9 a secured line delivered "
          "nothing through a discovery server (secured or not); use simple discovery for a secured line");
    }
    const ProfileRegistry* profiles = &registry;
    if (const auto dir = root["profiles_dir"]) {
      cfg.profiles_dir = file_path(src, dir, "profiles_dir");
      cfg.profiles = load_profiles_dir(src, dir, cfg.profiles_dir, registry, cfg.warnings);
      profiles = cfg.profiles.get();
    }
    const auto buses = src.required<YAML::Node>(root, "buses", "line configuration");
    src.expect_sequence(buses, "buses");
    if (buses.size() > kMaxBuses) src.fail(buses, "a line has at most " + std::to_string(kMaxBuses) + " buses");
    for (const auto& b : buses) {
      auto bus = parse_bus(src, b);
      if (cfg.bus(bus.name) != nullptr) src.fail(b["name"], "bus name '" + bus.name + "' is used twice");
      // Two masters on one network hear each other's SYNC and NMT: one line, one master per bus.
      for (const auto& other : cfg.buses) {
        if (other.interface == bus.interface && masters(other.role) && masters(bus.role)) {
          src.fail(b["interface"],
                   "bus " + bus.name + ": " + bus.interface + " is already bus " + other.name +
                       ", and both are masters: a CAN network has one NMT master and one SYNC producer");
        }
      }
      cfg.buses.push_back(std::move(bus));
    }
    check_recordings(src, buses, cfg.buses);
    const auto devices = src.required<YAML::Node>(root, "devices", "line configuration");
    src.expect_sequence(devices, "devices");
    Taken taken;
    for (const auto& d : devices) cfg.devices.push_back(parse_device(src, d, cfg, *profiles, cfg.warnings, taken));
    warn_identity_by_profile_number_alone(cfg);
    // A reaction chosen for mandatory devices when none is: most likely a forgotten `mandatory: true`.
    if (const auto startup = root["startup"];
        startup && startup["when_mandatory_fails"] &&
        std::none_of(cfg.devices.begin(), cfg.devices.end(), [](const DeviceConfig& d) { return d.mandatory; })) {
      cfg.warnings.push_back(
          src.where(startup["when_mandatory_fails"]) +
          ": when_mandatory_fails is set but no device is mandatory (mandatory: true): it has no effect");
    }
    return cfg;
  } catch (const ConfigError& e) {
    return make_error(e.what());
  } catch (const YAML::Exception& e) {  // a conversion the checks above missed: still an error, not an abort
    return make_error(source + ":" + std::to_string(e.mark.line + 1) + ":" + std::to_string(e.mark.column + 1) + ": " +
                      e.msg);
  }
}

Result<LineConfig> load_line_config(const std::string& path, const ProfileRegistry& registry) {
  auto text = read_config_file(path, "line configuration");
  if (!text) return text.error();
  return parse_line_config(*text, path, registry);
}

}  // namespace lb::profiles
