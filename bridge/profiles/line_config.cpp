#include "profiles/line_config.hpp"

#include <fstream>
#include <regex>
#include <sstream>

#include "profiles/yaml_source.hpp"

namespace lb::profiles {
namespace {

// Names become parts of DDS topic names: keep them to what ROS 2 allows there.
void check_name(const YamlSource& src, const YAML::Node& node, const std::string& name) {
  static const std::regex valid("[A-Za-z][A-Za-z0-9_]*");
  if (!std::regex_match(name, valid)) {
    src.fail(node, "'" + name + "' is not a valid name (a letter, then letters, digits or '_')");
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

DdsConfig parse_dds(const YamlSource& src, const YAML::Node& n) {
  src.check_keys(n, "dds", {"domain", "localhost_only"});
  DdsConfig dds;
  dds.domain = bounded<std::uint32_t>(src, n, "domain", 0, 0, 232, "dds");  // DDS/RTPS port mapping limit
  dds.localhost_only = src.optional<bool>(n, "localhost_only").value_or(true);
  return dds;
}

BusConfig parse_bus(const YamlSource& src, const YAML::Node& n) {
  src.check_keys(n, "bus", {"name", "interface", "role", "sync_period_ms"});
  BusConfig bus;
  bus.name = src.required<std::string>(n, "name", "bus");
  check_name(src, n["name"], bus.name);
  bus.interface = src.required<std::string>(n, "interface", "bus");
  if (bus.interface.rfind("socketcan:", 0) != 0 && bus.interface.rfind("virtual:", 0) != 0) {
    src.fail(n["interface"], "interface must be socketcan:<ifname> or virtual:<name>, not '" + bus.interface + "'");
  }
  const auto role = src.optional<std::string>(n, "role").value_or("master");
  if (role != "master" && role != "monitor") src.fail(n["role"], "role must be master or monitor, not '" + role + "'");
  bus.role = role == "master" ? BusRole::master : BusRole::monitor;
  bus.sync_period = std::chrono::milliseconds(bounded<int>(src, n, "sync_period_ms", 20, 1, 10'000, "bus " + bus.name));
  return bus;
}

SimulationConfig parse_simulation(const YamlSource& src, const YAML::Node& n) {
  src.check_keys(n, "simulation", {"max_speed_m_per_min", "acceleration_m_per_min_s", "scaling_pulses_per_m", "heartbeat_period_ms"});
  SimulationConfig sim;
  sim.max_speed_m_per_min = positive(src, n, "max_speed_m_per_min", sim.max_speed_m_per_min);
  sim.acceleration_m_per_min_s = positive(src, n, "acceleration_m_per_min_s", sim.acceleration_m_per_min_s);
  sim.scaling_pulses_per_m = bounded<std::uint32_t>(src, n, "scaling_pulses_per_m", sim.scaling_pulses_per_m, 1, 100'000'000, "simulation");
  sim.heartbeat_period = std::chrono::milliseconds(bounded<int>(src, n, "heartbeat_period_ms", 100, 1, 65535, "simulation"));
  return sim;
}

DeviceConfig parse_device(const YamlSource& src, const YAML::Node& n, const LineConfig& line,
                          const ProfileRegistry& registry) {
  src.check_keys(n, "device", {"name", "bus", "node_id", "profile", "version", "heartbeat_timeout_ms", "simulation"});
  DeviceConfig dev;
  dev.name = src.required<std::string>(n, "name", "device");
  check_name(src, n["name"], dev.name);
  if (line.device(dev.name) != nullptr) src.fail(n["name"], "device name '" + dev.name + "' is used twice");
  dev.bus = src.required<std::string>(n, "bus", "device " + dev.name);
  if (line.bus(dev.bus) == nullptr) src.fail(n["bus"], "device " + dev.name + ": no bus named '" + dev.bus + "'");
  if (!n["node_id"]) src.fail(n, "device " + dev.name + ": missing required key 'node_id'");
  dev.node_id = bounded<std::uint8_t>(src, n, "node_id", 0, 1, 127, "device " + dev.name);
  for (const auto& other : line.devices) {
    if (other.bus == dev.bus && other.node_id == dev.node_id) {
      src.fail(n["node_id"], "device " + dev.name + ": node-ID " + std::to_string(dev.node_id) + " is already used by " +
                                 other.name + " on bus " + dev.bus);
    }
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
  dev.heartbeat_timeout =
      std::chrono::milliseconds(bounded<int>(src, n, "heartbeat_timeout_ms", 500, 1, 65535, "device " + dev.name));
  if (n["simulation"]) dev.simulation = parse_simulation(src, n["simulation"]);
  return dev;
}

}  // namespace

std::string_view to_string(BusRole role) { return role == BusRole::master ? "master" : "monitor"; }

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

Result<LineConfig> parse_line_config(const std::string& yaml_text, const std::string& source,
                                     const ProfileRegistry& registry) {
  const YamlSource src(source);
  try {
    const YAML::Node root = src.parse(yaml_text);
    if (!root.IsMap()) src.fail(root, "a line configuration must be a mapping with line, buses and devices");
    src.check_keys(root, "line configuration", {"line", "dds", "buses", "devices"});
    LineConfig cfg;
    cfg.line = src.required<std::string>(root, "line", "line configuration");
    check_name(src, root["line"], cfg.line);
    if (root["dds"]) cfg.dds = parse_dds(src, root["dds"]);
    const auto buses = src.required<YAML::Node>(root, "buses", "line configuration");
    src.expect_sequence(buses, "buses");
    for (const auto& b : buses) {
      auto bus = parse_bus(src, b);
      if (cfg.bus(bus.name) != nullptr) src.fail(b["name"], "bus name '" + bus.name + "' is used twice");
      cfg.buses.push_back(std::move(bus));
    }
    const auto devices = src.required<YAML::Node>(root, "devices", "line configuration");
    src.expect_sequence(devices, "devices");
    for (const auto& d : devices) cfg.devices.push_back(parse_device(src, d, cfg, registry));
    return cfg;
  } catch (const ConfigError& e) {
    return make_error(e.what());
  }
}

Result<LineConfig> load_line_config(const std::string& path, const ProfileRegistry& registry) {
  std::ifstream in(path);
  if (!in) return make_error(path + ": cannot open the line configuration");
  std::stringstream text;
  text << in.rdbuf();
  return parse_line_config(text.str(), path, registry);
}

}  // namespace lb::profiles
