#pragma once
// One PDO's CiA 301 parameters as a device keeps them (communication 1400h/1800h + n, mapping
// 1600h/1A00h + n), the device's power-on values, and the checks a device makes when a master
// writes them. Pure values and functions: DevicePdos applies them on the bus.
//
// What CiA 301 refuses while the PDO is valid (COB-ID bit 31 = 0), as Lely CANopen's slave does
// (the download indications of 1400h/1800h and 1600h/1A00h in lely-core src/co/rpdo.c, tpdo.c),
// each with the code Lely answers, CO_SDO_AC_PARAM_VAL = 0609 0030h "value range of parameter
// exceeded": another identifier (or bit 29) in sub 1 (only bit 31 may change); the inhibit time
// (sub 3); the mapping (sub 0 and the entries). A write of the value the entry already has is
// accepted, as Lely accepts it. The transmission type (sub 2) and the event timer (sub 5) may be
// written at any time. Where the profile fixes the COB-ID (const, ro) the PDO can never be made
// invalid: a mapping the profile still lets a master write (CiA 420-4 3.1 1A00h sub 0 "rw (constant
// in NMT operational state)", puller 1.0's CiA 301 rw mapping) is then taken while the device is
// not operational, as the profile's own table says, else it could never be written at all; the
// inhibit time of such a PDO cannot be written (the bridge's boot reports it, README).
//
// Abort codes of refused writes (CiA 301, and the profile's table of what a master may write):
//   06010002h  an entry the profile makes const or ro (the dictionary refuses it by its access);
//   06090030h  a COB-ID change the profile or CiA 301 does not allow (only bit 31 where only the
//              valid bit is writable; identifier or bit 29 of a valid PDO; an 11-bit identifier
//              above 7FFh or a restricted one); a reserved transmission type; a mapping count
//              beyond the entries the PDO has or outside the profile's list; the inhibit time, a
//              mapping count or entry of a valid PDO (above); an entry while sub 0 is not 0;
//   08000022h  an entry written in a state that forbids it: "rw (constant in NMT operational
//              state)" while operational; the mapping of a PDO whose COB-ID is fixed while
//              operational;
//   06020000h  a mapping entry naming an object the dictionary lacks;
//   06040041h  an object that cannot be mapped (not a process value of the device, a string, not
//              readable in a TPDO, not writable in an RPDO, a dummy in a TPDO, a wrong length);
//   06040042h  entries 1..n longer than 64 bits.

#include <cstdint>
#include <optional>
#include <vector>

#include "canopen/pdo_mapping.hpp"
#include "canopen/pdo_parameters.hpp"
#include "canopen/process_image.hpp"
#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"

namespace lb::sim {

// The COB-ID entry's bits are canopen's (pdo_parameters.hpp), the same for device and master.
namespace cob_bits {
inline constexpr std::uint32_t invalid = canopen::kCobIdNotValid;
inline constexpr std::uint32_t no_rtr = canopen::kCobIdNoRtr;
inline constexpr std::uint32_t extended = canopen::kCobIdExtended;
inline constexpr std::uint32_t identifier = canopen::kCobIdIdentifier;
}  // namespace cob_bits

struct PdoParameters {
  std::uint32_t cob_id = 0;  // sub 1: the whole CiA 301 entry
  std::uint8_t transmission_type = 1;
  std::uint16_t inhibit_time = 0;      // sub 3, 100 µs
  std::uint16_t event_timer = 0;       // sub 5, ms
  std::uint8_t count = 0;              // mapping sub 0: entries 1..count are mapped
  std::vector<std::uint32_t> entries;  // mapping subs 1..n the device has, mapped or not

  bool valid() const { return (cob_id & cob_bits::invalid) == 0; }
  bool extended() const { return (cob_id & cob_bits::extended) != 0; }
  std::uint32_t can_id() const { return cob_id & (extended() ? cob_bits::identifier : 0x7FFU); }
  bool synchronous() const { return transmission_type <= 240; }
  std::vector<canopen::PdoEntry> mapped() const;  // entries 1..count
};

// The manufacturer-specific objects the simulated devices map where a profile leaves an entry to
// the manufacturer (CiA 420-3/-4 3.1: "one and only one manufacturer-specific process data").
inline constexpr std::uint16_t kSecondStatusWord = 0x2110;   // UNSIGNED16 ro, TPDOs: counts SYNCs while operational
inline constexpr std::uint16_t kSecondControlWord = 0x2111;  // UNSIGNED16 rw, RPDOs: kept, not interpreted

// A PDO's parameters as the device comes out of power-on: the profile's default (COB-ID with bit
// 30 as the specs write it, the default mapping, its manufacturer-specific entries after it,
// present but not counted), replaced by the device's own `simulation.pdos` where given. Checks
// what needs no dictionary (identifier, transmission type); throws std::runtime_error.
PdoParameters power_on_parameters(const profiles::PdoDef& def, const profiles::DeviceConfig& device);

// Highest sub-index of the communication parameter: 5 with an event timer, 3 with only an inhibit
// time, else 2 (sub 4 is reserved; sub 6, the SYNC start value, is not implemented).
std::uint8_t highest_communication_sub(const profiles::PdoRules& rules);

// Each returns the abort code of a refused write, nullopt for an accepted one. `operational`:
// the device's NMT state is operational.
std::optional<std::uint32_t> check_cob_id(profiles::PdoDirection direction, profiles::PdoAccess access,
                                          std::uint32_t current, std::uint32_t wanted);
std::optional<std::uint32_t> check_transmission_type(profiles::PdoDirection direction, std::uint8_t type);
// The profile's state rule, before any other check: 08000022h for "rw (constant in NMT
// operational state)" while operational.
std::optional<std::uint32_t> check_state(profiles::PdoAccess access, bool operational);
// A master can make the PDO not valid: its COB-ID is writable, or at least its valid bit.
bool can_invalidate(const profiles::PdoRules& rules);
// CiA 301's rule for the inhibit time (sub 3): only while the PDO is not valid (0609 0030h).
// `wanted` equal to the value it has is accepted.
std::optional<std::uint32_t> check_inhibit_time(const PdoParameters& pdo, std::uint16_t wanted);
// CiA 301's rule for the mapping (sub 0 and the entries) of a valid PDO: 0609 0030h where a master
// could have made it invalid; where the profile fixes the COB-ID, 08000022h while operational.
// Called only for a value that differs from the one the entry has.
std::optional<std::uint32_t> check_mapping_while_valid(const PdoParameters& pdo, const profiles::PdoRules& rules,
                                                       bool operational);
std::optional<std::uint32_t> check_mapping_count(const PdoParameters& pdo, const profiles::PdoRules& rules,
                                                 std::uint8_t count);
// An entry (also one of the power-on mapping): the object must be a process value of the device
// (in `image`, described by `dictionary`) that the direction can carry, with its exact length.
std::optional<std::uint32_t> check_mapping_entry(profiles::PdoDirection direction, std::uint32_t entry,
                                                 const canopen::ObjectDictionary& dictionary,
                                                 const canopen::ProcessImage& image);

}  // namespace lb::sim
