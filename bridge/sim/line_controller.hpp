#pragma once
// A stand-in for a line's real controller (the extruder's NMT master), for tests and demos of the
// monitor role: SYNC at the bus's period, NMT start of every device after its boot-up, and each
// device's RPDOs at every SYNC, filled from simulation.controller_values.

#include <memory>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/process_image.hpp"
#include "canopen/sync_producer.hpp"
#include "profiles/line_config.hpp"

namespace lb::sim {

class LineController {
 public:
  LineController(canopen::BusLoop& loop, const profiles::BusConfig& bus,
                 const std::vector<const profiles::DeviceConfig*>& devices);
  void start();  // loop thread or before the loop starts

 private:
  struct Rpdo {
    std::uint32_t can_id;
    bool extended;
    canopen::PdoBinding binding;
    const canopen::ProcessImage* image;
  };

  canopen::BusLoop& loop_;
  canopen::SyncProducer sync_;
  std::vector<std::unique_ptr<canopen::ProcessImage>> images_;  // stable addresses for the bindings
  std::vector<Rpdo> rpdos_;
  std::vector<std::uint8_t> nodes_;
};

}  // namespace lb::sim
