#pragma once
// The CiA 301 device side every simulated device shares, so that a device simulator is only its
// dynamics. A simulated device knows its profile's defaults, its `simulation:` section (its
// "hardware": identity, factory PDO parameters, faults) and what reaches it over CAN, nothing of
// what the line configuration tells the bridge (pdos, configure, identity, ...).
//
//  - Object dictionary (device_dictionary.hpp) served by SDO, except in NMT stopped, where the
//    server is silent. Every numeric profile object (and every application object a simulator
//    adds) lives in one process image: SDO reads and writes, PDOs and the simulation all see the
//    same value.
//  - PDOs as CiA 301 and the profile let a master configure them (device_pdos.hpp).
//  - NMT (nmt_slave.hpp): reset node restores every power-on value, application objects as the
//    simulator's reset defines them and every communication object (PDO parameters, 1017h);
//    reset communication only the communication objects. Both drop pending RPDOs and the SDO
//    transfer in progress, then send the boot-up. Leaving operational drops pending RPDOs.
//  - SYNC while operational: pending synchronous RPDOs take effect, the application steps, the
//    second status word (2110h) counts, then the TPDOs go.
//  - An RPDO shorter than its mapping is not applied: counted, logged, and EMCY 8210h at most
//    once a second (manufacturer bytes: the PDO's number, the length received, the length needed).
//  - Simulation control 2002h (UNSIGNED8, wo), for tests of a master: 1 = reset node, 2 = reset
//    communication, both without the boot-up message (a device whose boot-up a master missed).
//    The write is confirmed first; the device is then pre-operational with its power-on values
//    and sends heartbeats if its power-on 1017h is not 0.
//  - `simulation.ignore_writes`: those objects confirm an SDO write and keep their value.
//  - 1016h heartbeat consumer, one entry (sim/heartbeat_consumer.hpp): a consumed heartbeat
//    missing raises EMCY 8130h and takes an operational device to pre-operational (1029h sub 1
//    default); its return clears the error (the device stays pre-operational until a master
//    starts it).
//  - Errors (CiA 301): the device keeps its active errors; 1001h is the error register (bit 0
//    generic whenever one is active, plus the family's bit: current, voltage, temperature,
//    communication). raise_error() sends the code's EMCY; clear_error() sends EMCY 0000h with the
//    register that remains, so a master sees "error reset" while other errors are still active.
//    Reset node clears them.
//  - 1003h, the pre-defined error field (unless simulation.pre_defined_error_field is false), is
//    the error HISTORY, not the active list: every EMCY the device sends is recorded there, the
//    error resets (0000h) included, as CANopenNode does. Sub 0 the number recorded, sub 1 the
//    newest, older ones shift up; at most kErrorFieldEntries, the oldest dropped. Each entry:
//    bits 0..15 the error code, bits 16..31 (manufacturer-specific additional information) 0.
//    Writing 0 to sub 0 empties the history (the errors stay active, no EMCY); any other value is
//    refused with abort 0609 0030h; subs 1..n are read-only. Reset node empties it (power-on).
//    Error simulation 2003h (UNSIGNED32, wo), for tests of a master: bits 0..15 an error code to
//    raise; with bit 31 set the code to clear (0000h with bit 31: clear all).

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/cob_id.hpp"
#include "canopen/process_image.hpp"
#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"
#include "sim/device_pdos.hpp"
#include "sim/heartbeat_consumer.hpp"
#include "sim/nmt_slave.hpp"

namespace lb::sim {

class SimulatedNode {
 public:
  struct Application {
    std::function<void()> reset;            // power-on and reset node, after the image went to 0
    std::function<void(double dt_s)> step;  // every SYNC while operational: after the RPDOs, before the TPDOs
    // An RPDO's values reached the image (synchronous ones at the SYNC, before the step).
    std::function<void(std::span<const canopen::PdoEntry> mapped)> received;
    // TPDOs whose event (types 254/255) is the application's (SimulatedNode::event), as the
    // profile defines it, rather than a change of their data.
    std::vector<std::string> event_tpdos;
  };

  // Before the loop starts. Throws std::runtime_error (start-up) on a profile or simulation
  // section the device cannot have.
  SimulatedNode(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile,
                Application application);
  SimulatedNode(const SimulatedNode&) = delete;
  SimulatedNode& operator=(const SimulatedNode&) = delete;

  // Power-on: every value to its power-on value, boot-up, pre-operational. Once, when the
  // application and its objects are complete (loop thread or before the loop starts); throws
  // std::runtime_error when a power-on PDO mapping names an object the device cannot map or
  // simulation.ignore_writes an object it does not have.
  void boot();

  canopen::NmtState state() const { return nmt_.state(); }
  canopen::ProcessImage& image() { return image_; }
  // Slot of a profile object; throws std::runtime_error when the profile has none of that name.
  std::size_t slot(std::string_view object) const;
  // A flag of a profile bit set; nullopt when the profile (version) lacks it.
  std::optional<unsigned> bit(std::string_view set, std::string_view name) const;
  // A value of the image by object, 0 for an object the image does not hold.
  std::uint64_t get(std::uint16_t index, std::uint8_t sub) const;
  void set(std::uint16_t index, std::uint8_t sub, std::uint64_t raw);

  // Construction time: a manufacturer-specific object of the application, in the image (SDO
  // reads and writes, mappable into PDOs, 0 after reset node). Throws std::runtime_error.
  std::size_t add_object(std::uint16_t index, canopen::DataType type, canopen::ObjectAccess access,
                         std::optional<std::int64_t> min = {}, std::optional<std::int64_t> max = {});
  // Construction time: a check of SDO writes to an object of the image, before the value is
  // stored: an abort code refuses the write. Throws std::runtime_error for objects not in the image.
  void check_writes(std::uint16_t index, std::uint8_t sub, canopen::ObjectDictionary::WriteHook check);
  // Construction time: a command object outside the image (not mappable; 0 again after reset
  // node), with the hook that serves its writes. Throws std::runtime_error.
  void add_command(std::uint16_t index, canopen::DataType type, canopen::ObjectDictionary::WriteHook hook);

  // Loop thread: an application event of a TPDO (see DevicePdos::event).
  void event(std::string_view tpdo) { (void)pdos_.event(tpdo); }
  // EMCY on 1014h; the error register (1001h) becomes `error_register`.
  void send_emergency(std::uint16_t code, std::uint8_t error_register, std::array<std::uint8_t, 5> manufacturer);
  // Loop thread: an error becomes active (again: its EMCY is sent again, with new manufacturer bytes).
  void raise_error(std::uint16_t code, std::array<std::uint8_t, 5> manufacturer = {});
  // Loop thread: an error is no longer active. `last_word`: the code's EMCY is sent once more with
  // these bytes (and the register that remains) before the error reset, as a feeder box does.
  void clear_error(std::uint16_t code, std::optional<std::array<std::uint8_t, 5>> last_word = std::nullopt);

 private:
  void on_reset(NmtSlave::Reset kind);
  void on_state(canopen::NmtState from, canopen::NmtState to);
  void on_sync();
  void listen_for_sync(std::uint32_t id);
  void on_short_rpdo(const profiles::PdoDef& pdo, std::size_t length, std::size_t needed);
  void link_image_objects();
  void link_communication_objects();
  void serve_from_image(std::uint16_t index, std::uint8_t sub, std::size_t slot);
  void link_error_objects();
  std::uint8_t register_of_active() const;

  canopen::BusLoop& loop_;
  const profiles::DeviceConfig& device_;
  const profiles::Profile& profile_;
  Application app_;
  canopen::ProcessImage image_;
  std::vector<std::size_t> image_slots_;  // every slot of the image, for reset node
  std::vector<std::uint16_t> commands_;   // add_command's objects, for reset node
  NmtSlave nmt_;
  canopen::SdoServer sdo_;
  DevicePdos pdos_;
  HeartbeatConsumer consumer_;                     // 1016h
  std::optional<std::size_t> second_status_word_;  // 2110h, where a TPDO has a manufacturer entry
  std::chrono::milliseconds heartbeat_period_{0};  // 1017h
  std::uint8_t error_register_ = 0;                // 1001h
  std::vector<std::uint16_t> active_errors_;       // oldest first; what 1001h reflects
  std::vector<std::uint32_t> error_history_;       // 1003h sub 1.. : newest first, every EMCY sent
  std::optional<std::chrono::steady_clock::time_point> last_sync_;
  std::uint32_t sync_id_ = canopen::cob::sync;  // 1005h bits 0..10
  std::set<std::uint32_t> sync_ids_;            // identifiers with a SYNC handler
  std::uint64_t short_rpdos_ = 0;
  std::optional<std::chrono::steady_clock::time_point> last_short_emcy_;
};

}  // namespace lb::sim
