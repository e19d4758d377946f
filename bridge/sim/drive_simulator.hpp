#pragma once
// The device side of a CiA 420 puller (part 2) or corrugator (part 3): the drive starts and stops
// on the control word's start/stop buttons, its speed ramps to the set value (6002h, 0.01 % of the
// speed set maximum 6003h) while it runs, the load follows the speed, the product speed follows
// from speed and 6003h, functions f1..f3 start and stop, a puller's clamp closes and opens, and a
// corrugator asks for a cut (status bit 14) every metre of product.
//
// Local operation, for the master's set echo check: manufacturer-specific objects
//   2100h UNSIGNED8  local mode (0 = remote: follows 6002h; 1 = local: follows 2101h), default 0
//   2101h INTEGER16  local speed set value, 0.01 %, -10000..10000
// In local mode the device runs and echoes (6004h) the local set value, as CiA 420-2 3.0 says a
// puller in local mode does; a profile with a speed set mode bit (3.0 status word) reports it.
// Both are process values of the device: reset node clears them, a master may map them.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "profiles/line_config.hpp"
#include "sim/device_simulator.hpp"
#include "sim/simulated_node.hpp"

namespace lb::sim {

class DriveSimulator : public DeviceSimulator {
 public:
  static constexpr std::uint16_t kLocalModeIndex = 0x2100;
  static constexpr std::uint16_t kLocalSpeedIndex = 0x2101;

  DriveSimulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile);
  void start() override;

 private:
  using Clock = std::chrono::steady_clock;
  // Start/stop buttons and the state they switch (the drive, a function f1..f3, the clamp).
  struct Switch {
    std::optional<unsigned> on_button, off_button, running_bit, ready_bit;
    bool running = false;
  };

  Switch make_switch(const std::string& on, const std::string& off, const std::string& running,
                     const std::string& ready) const;
  void reset();
  void step(double dt_s);
  void operate(Switch& s, std::uint64_t cw) const;
  void add_local_objects();

  const profiles::DeviceConfig& device_;
  const profiles::Profile& profile_;
  SimulatedNode node_;
  std::size_t status_word_, control_word_, speed_actual_, speed_set_, speed_echo_, speed_set_max_, speed_real_max_,
      load_actual_, product_speed_, scaling_factor_, configuration_word_;
  Switch drive_, clamp_;
  Switch functions_[3];
  std::optional<unsigned> sw_reverse_, sw_master_extruder_enabled_, sw_cut_pulse_;
  std::optional<std::uint64_t> mode_remote_, mode_local_;  // 3.0 status word: speed set mode codes
  std::uint64_t mode_mask_ = 0;

  std::size_t local_mode_, local_speed_;  // 2100h, 2101h in the node's image

  std::uint64_t last_cw_ = 0;
  double speed_percent_ = 0;
  double product_since_cut_m_ = 0;
  Clock::time_point cut_pulse_until_{};
};

}  // namespace lb::sim
