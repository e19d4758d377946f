#pragma once
// One YAML file describes a line: DDS settings, buses and devices. Loading validates everything
// (keys, ranges, references, profiles) so nothing starts half-configured.

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "profiles/profile_registry.hpp"

namespace lb::profiles {

enum class BusRole { master, monitor };
std::string_view to_string(BusRole role);

struct DdsConfig {
  std::uint32_t domain = 0;
  bool localhost_only = true;
};

struct BusConfig {
  std::string name;
  std::string interface;  // "socketcan:can0", "virtual:demo"
  BusRole role = BusRole::master;
  std::chrono::microseconds sync_period{20'000};  // CiA 420-1: 20 ms
};

// Only read by linebridge-sim: how the simulated device behaves.
struct SimulationConfig {
  double max_speed_m_per_min = 30.0;       // line speed at 100 % sync speed
  double acceleration_m_per_min_s = 60.0;  // speed ramp
  std::uint32_t scaling_pulses_per_m = 10'000;
  std::chrono::milliseconds heartbeat_period{100};
};

struct DeviceConfig {
  std::string name;
  std::string bus;
  std::uint8_t node_id = 0;
  std::string profile;
  std::string version;
  std::chrono::milliseconds heartbeat_timeout{500};
  SimulationConfig simulation;
  const Profile* resolved_profile = nullptr;  // points into the registry the config was loaded with
};

struct LineConfig {
  std::string line;
  DdsConfig dds;
  std::vector<BusConfig> buses;
  std::vector<DeviceConfig> devices;

  const BusConfig* bus(std::string_view name) const;
  const DeviceConfig* device(std::string_view name) const;
};

// `source` names the text in error messages (the file path). The registry must outlive the result.
Result<LineConfig> parse_line_config(const std::string& yaml_text, const std::string& source,
                                     const ProfileRegistry& registry);
Result<LineConfig> load_line_config(const std::string& path, const ProfileRegistry& registry);

}  // namespace lb::profiles
