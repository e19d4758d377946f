#pragma once
// linebridge-cli set: a device's set values, whatever its type. Fields not given keep the value in
// force, which the device's status topic reports (a feeder's loom parts not given are not sent).
// A device with no set value in force yet (its status reports them all 0) has no value to keep:
// then the values (speeds, lengths) must be given, else nothing is sent (exit 2); a stop needs none.

#include <optional>
#include <string>
#include <vector>

#include "dds/participant.hpp"

namespace lb::app {

struct SetOptions {
  // saw
  std::optional<std::string> program;          // on, off
  std::optional<std::string> wall_thickening;  // on, off
  std::optional<double> sync_speed_percent;
  std::optional<double> product_length_m;
  std::optional<std::string> count_mode;  // smooth, corrugated
  // puller, corrugator
  std::optional<std::string> extruder;  // running, stopped
  std::optional<double> speed_percent;
  // feeder (the bridge plays the loom controller)
  std::optional<std::string> loom_status;
  std::optional<unsigned> maximum_speed_per_min;
  std::optional<double> loom_width_m;
  std::optional<std::string> trigger_signal;
  std::vector<unsigned> picks;
  std::vector<unsigned> outputs;
  double timeout_s = 5;
};

// Which options a device type takes, for refusals of the others.
std::string set_options_of(const std::string& device_type);

// Returns the exit code (cli_exit.hpp).
int run_set(ddsl::Participant& dds, const std::string& line, const std::string& device, const std::string& device_type,
            const SetOptions& options);

}  // namespace lb::app
