#pragma once
// The CANopen side every simulated CiA 420 device shares, so a device simulator is only its
// dynamics: a process image holding every object of the profile, NMT and heartbeat, an SDO server
// over the whole dictionary (writes of profile objects reach the image at once), synchronous RPDOs
// applied at the next SYNC, and TPDOs sent after each SYNC.

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

#include "canopen/pdo_transmitter.hpp"
#include "canopen/process_image.hpp"
#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"
#include "sim/nmt_slave.hpp"

namespace lb::sim {

class SimulatedNode {
 public:
  struct Application {
    std::function<void()> reset;            // power-on and NMT reset node: application values to defaults
    std::function<void(double dt_s)> step;  // every SYNC when operational: RPDOs applied, TPDOs follow
  };

  // Throws std::runtime_error (start-up) on a PDO the profile cannot map. Call reset() once the
  // application is ready for it (the application's reset usually needs the node's slots).
  SimulatedNode(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile,
                Application application);
  SimulatedNode(const SimulatedNode&) = delete;
  SimulatedNode& operator=(const SimulatedNode&) = delete;

  void boot() { nmt_.boot(); }
  void reset();

  canopen::ProcessImage& image() { return image_; }
  canopen::ObjectDictionary& dictionary() { return sdo_.dictionary(); }
  canopen::NmtState state() const { return nmt_.state(); }
  // Slot of a profile object; throws std::runtime_error when the profile has none of that name.
  std::size_t slot(std::string_view object) const;
  // A flag of a profile bit set; nullopt when the profile (version) lacks it.
  std::optional<unsigned> bit(std::string_view set, std::string_view name) const;

 private:
  struct Rpdo {
    const profiles::DevicePdo* def;
    canopen::PdoBinding binding;
    std::optional<can::CanFrame> pending;  // synchronous: applied at the next SYNC
  };
  void on_sync();
  void apply_rpdo(Rpdo& rpdo, const can::CanFrame& frame);
  void link_dictionary();
  void publish_to_dictionary();

  canopen::BusLoop& loop_;
  const profiles::DeviceConfig& device_;
  const profiles::Profile& profile_;
  Application app_;
  canopen::ProcessImage image_;
  NmtSlave nmt_;
  canopen::SdoServer sdo_;
  std::vector<canopen::PdoBinding> tpdo_bindings_;
  std::vector<std::unique_ptr<canopen::PdoTransmitter>> tpdos_;
  std::vector<Rpdo> rpdos_;
  std::optional<std::chrono::steady_clock::time_point> last_sync_;
  std::uint64_t short_rpdos_ = 0;
};

}  // namespace lb::sim
