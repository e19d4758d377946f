#pragma once
// The dynamics of a CiA 420-4 saw: the saw counter grows with the product speed, the saw cuts when
// it reaches the set length, the status word reports it. Its CANopen side is SimulatedNode's.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string_view>

#include "profiles/line_config.hpp"
#include "sim/device_simulator.hpp"
#include "sim/simulated_node.hpp"

namespace lb::sim {

class SawSimulator : public DeviceSimulator {
 public:
  SawSimulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile);
  void start() override;

 private:
  using Clock = std::chrono::steady_clock;

  unsigned required_bit(std::string_view set, std::string_view name) const;
  void reset();
  void step(double dt_s);

  const profiles::DeviceConfig& device_;
  SimulatedNode node_;
  std::size_t status_word_, control_word_, counter_value_, saw_counter_, product_speed_, sync_speed_set_, length_set_,
      speed_max_, configuration_word_;
  unsigned cw_program_on_, cw_change_of_length_, sw_ready_, sw_cutting_, sw_program_enabled_;

  double speed_mm_per_min_ = 0;
  double saw_counter_01mm_ = 0;
  double pulses_ = 0;
  bool program_was_on_ = false;
  bool last_change_bit_ = false;
  std::uint64_t active_length_ = 0;
  std::optional<std::uint64_t> pending_length_;
  Clock::time_point cutting_until_{};
};

}  // namespace lb::sim
