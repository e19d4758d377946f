#pragma once
// The object dictionary of a simulated device, as it comes out of power-on: every object of its
// profile, the CiA 301 communication objects a master reads or writes, the identity, and the
// manufacturer-specific objects below. The PDO parameters (1400h..1BFFh) are added by DevicePdos,
// which owns their values; SimulatedNode serves the process values from its image.
//
//   1000h  device type: the profile's, or simulation.identity.device_type
//   1001h  error register          1005h  COB-ID SYNC 0000 0080h      1014h  COB-ID EMCY 80h + node-ID
//   1003h  pre-defined error field, the error history (every EMCY sent, newest at sub 1):
//          sub 0 UNSIGNED8 rw (the count; writing 0 clears), sub 1..8 UNSIGNED32 ro; absent
//          with simulation.pre_defined_error_field: false
//   1008h/1009h/100Ah  device name, hardware and software version (visible strings)
//   1017h  heartbeat producer time, power-on value simulation.heartbeat_period_ms (0: none)
//   1018h  identity, sub 0 = 4; each value replaced by simulation.identity where given:
//          vendor-ID 4C42 0000h ("LB"), product code by device type (see product_code()),
//          revision 0001 0000h, serial number 5100 0000h + node-ID
//   2000h  VISIBLE_STRING rw: a free text the line can store in the device (segmented both ways)
//   2002h  UNSIGNED8 wo: simulation control, 1 = reset node, 2 = reset communication, both
//          without the boot-up message (simulated_node.hpp)
//   2003h  UNSIGNED32 wo: error simulation, bits 0..15 a code to raise, bit 31 set: to clear
//   2110h  UNSIGNED16 ro: second status word, where a TPDO has a manufacturer-specific entry
//   2111h  UNSIGNED16 rw: second control word, where an RPDO has a manufacturer-specific entry

#include <cstdint>
#include <string>
#include <string_view>

#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"

namespace lb::sim {

inline constexpr std::uint16_t kDeviceText = 0x2000;
inline constexpr std::uint16_t kSimulationControl = 0x2002;
inline constexpr std::uint16_t kErrorSimulation = 0x2003;
inline constexpr std::uint16_t kErrorField = 0x1003;
inline constexpr std::uint8_t kErrorFieldEntries = 8;

// The simulator's product code (1018h sub 2) of a device type: its registry entry's
// (profiles/device_types.hpp: CiA part number in the high word); 0 for a type it lacks.
std::uint32_t product_code(std::string_view device_type);

// Throws std::runtime_error (start-up) on a profile the dictionary cannot represent.
canopen::ObjectDictionary make_device_dictionary(const profiles::DeviceConfig& device,
                                                 const profiles::Profile& profile);

// The long, segmented-transfer-sized device name the simulators report in 1008h.
std::string simulated_device_name(const profiles::DeviceConfig& device, const profiles::Profile& profile);

}  // namespace lb::sim
