#pragma once
// The PDOs of one simulated device at run time, as CiA 301 has them: their parameters in the
// dictionary (communication 1400h/1800h + n, mapping 1600h/1A00h + n, the subs the profile's
// rules implement), checked and applied when a master writes them (pdo_parameters.hpp says how);
// TPDOs sent as the parameters say (transmission type, inhibit time, event timer, valid bit,
// 29-bit identifier, mapping count); RPDOs taken as they say (synchronous ones at the next SYNC,
// event-driven ones at once, none while not valid or not operational, short ones not applied).
//
// The bus loop cannot unregister a frame handler, so an RPDO gets one handler per identifier it
// ever had, each checking that it is still the PDO's; TPDO transmitters are made once and
// reconfigured (their timers cannot be destroyed either).

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/pdo_transmitter.hpp"
#include "canopen/process_image.hpp"
#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"
#include "sim/pdo_parameters.hpp"

namespace lb::sim {

class DevicePdos {
 public:
  struct Hooks {
    std::function<bool()> operational;  // the device's NMT state is operational
    // An RPDO's values reached the image; the entries it mapped.
    std::function<void(std::span<const canopen::PdoEntry> mapped)> received;
    // An RPDO shorter than its mapping arrived and was not applied.
    std::function<void(const profiles::PdoDef& pdo, std::size_t length, std::size_t needed)> too_short;
  };

  // Adds the PDO objects to `dictionary` and registers the power-on identifiers: before the loop
  // starts. `application_events`: TPDOs whose event (types 254/255) is the application's, as a
  // profile may define it (a feeder's TPDO1: one per winding), not a change of their data.
  // Throws std::runtime_error on a `simulation.pdos` entry the device cannot have.
  DevicePdos(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile,
             canopen::ProcessImage& image, canopen::ObjectDictionary& dictionary, Hooks hooks,
             const std::vector<std::string>& application_events);
  DevicePdos(const DevicePdos&) = delete;
  DevicePdos& operator=(const DevicePdos&) = delete;

  // Power-on parameters (NMT reset node, reset communication); pending RPDOs are dropped. The
  // first call checks the power-on mappings against the complete dictionary and throws
  // std::runtime_error when one names an object the device cannot map.
  void reset();
  void started();           // the device entered operational: counts restart, event timers run
  void left_operational();  // pending RPDOs are dropped
  void apply_pending();     // SYNC: synchronous RPDOs take effect
  void on_sync();           // SYNC, after the application's step: TPDOs
  void data_changed();      // the image changed outside a SYNC: change-driven TPDOs look
  // An application event of a TPDO (a new value, even an equal one): an event-driven TPDO goes
  // out now, inhibit time permitting. False when the profile has no such TPDO.
  bool event(std::string_view tpdo);

 private:
  struct Pdo {
    const profiles::PdoDef* def = nullptr;
    PdoParameters power_on;
    PdoParameters now;
    std::optional<canopen::PdoBinding> binding;             // entries 1..count
    std::unique_ptr<canopen::PdoTransmitter> transmitter;   // TPDOs
    std::optional<can::CanFrame> pending;                   // synchronous RPDO until the next SYNC
    std::vector<std::pair<std::uint32_t, bool>> listening;  // RPDO identifiers (id, 29-bit) with a handler
    bool application_events = false;                        // TPDO: event-driven by event() only, not by changed data
  };
  using Read = std::function<std::uint32_t()>;
  using Write = std::function<std::optional<std::uint32_t>(std::uint32_t)>;

  bool tx(const Pdo& p) const { return p.def->direction == profiles::PdoDirection::tx; }
  static canopen::PdoTransmitter::Settings settings(const PdoParameters& p);
  void add_objects(std::size_t i);
  void add(std::uint16_t index, std::uint8_t sub, canopen::DataType type, profiles::PdoAccess access, Read read,
           Write write);
  void listen(std::size_t i);
  void receive(Pdo& p, const can::CanFrame& frame);
  void apply(Pdo& p, const can::CanFrame& frame);
  void rebind(Pdo& p);
  void communication_changed(Pdo& p, std::size_t i);
  void check_power_on() const;

  std::optional<std::uint32_t> write_cob_id(std::size_t i, std::uint32_t v);
  // Transmission type, inhibit time, event timer: the state check, then the value's own
  // (out_of_range: its abort code, if any), then `set`.
  std::optional<std::uint32_t> write_communication(std::size_t i, profiles::PdoAccess access,
                                                   std::optional<std::uint32_t> out_of_range,
                                                   const std::function<void(Pdo&)>& set);
  std::optional<std::uint32_t> write_count(std::size_t i, std::uint32_t v);
  std::optional<std::uint32_t> write_entry(std::size_t i, std::size_t entry, std::uint32_t v);

  canopen::BusLoop& loop_;
  const profiles::DeviceConfig& device_;
  canopen::ProcessImage& image_;
  canopen::ObjectDictionary& dictionary_;
  Hooks hooks_;
  std::vector<Pdo> pdos_;  // the profile's PDOs, in its order; handlers refer to them by position
  bool checked_ = false;
};

}  // namespace lb::sim
