#pragma once
// The device side of a CiA 420-4 saw: applies RPDO1 at SYNC, lets the saw counter grow with the
// product speed, cuts when it reaches the set length, and answers with TPDO1/TPDO2 after each SYNC.

#include <chrono>
#include <memory>
#include <optional>
#include <vector>

#include "canopen/pdo_transmitter.hpp"
#include "canopen/process_image.hpp"
#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"
#include "sim/device_simulator.hpp"
#include "sim/nmt_slave.hpp"

namespace lb::sim {

class SawSimulator : public DeviceSimulator {
 public:
  SawSimulator(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile);
  void start() override;

 private:
  using Clock = std::chrono::steady_clock;

  std::size_t slot(std::string_view object);
  unsigned bit(std::string_view set, std::string_view name);
  void reset_application();
  void on_sync();
  void step(double dt_s);
  void publish_to_dictionary();
  void link_dictionary();  // SDO writes of image objects reach the image

  canopen::BusLoop& loop_;
  const profiles::DeviceConfig& device_;
  const profiles::Profile& profile_;
  canopen::ProcessImage image_;
  NmtSlave nmt_;
  canopen::SdoServer sdo_;
  struct Rpdo {
    const profiles::DevicePdo* def;
    canopen::PdoBinding binding;
    std::optional<can::CanFrame> pending;  // synchronous: applied at the next SYNC
  };
  void apply_rpdo(Rpdo& rpdo, const can::CanFrame& frame);

  std::vector<canopen::PdoBinding> tpdo_bindings_;
  std::vector<std::unique_ptr<canopen::PdoTransmitter>> tpdos_;
  std::vector<Rpdo> rpdos_;

  std::size_t status_word_, control_word_, counter_value_, saw_counter_, product_speed_, sync_speed_set_, length_set_,
      speed_max_;
  unsigned cw_program_on_, cw_change_of_length_, sw_ready_, sw_cutting_, sw_program_enabled_;

  std::optional<Clock::time_point> last_sync_;
  double speed_mm_per_min_ = 0;
  double saw_counter_01mm_ = 0;
  double pulses_ = 0;
  bool program_was_on_ = false;
  bool last_change_bit_ = false;
  std::uint64_t active_length_ = 0;
  std::optional<std::uint64_t> pending_length_;
  Clock::time_point cutting_until_{};
  std::uint64_t short_rpdos_ = 0;
};

}  // namespace lb::sim
