#pragma once
// One PDO's communication and mapping parameters as a device keeps them (1400h..1BFFh), what a
// master wants of them, and the CiA 301 writes that take a device from one to the other, refused
// where the device profile fixes the entry that differs. Pure logic: BootSequence reads and writes.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "canopen/pdo_mapping.hpp"
#include "canopen/pdo_rules.hpp"

namespace lb::canopen {

inline constexpr std::uint32_t kCobIdNotValid = 0x8000'0000U;
inline constexpr std::uint32_t kCobIdNoRtr = 0x4000'0000U;
inline constexpr std::uint32_t kCobIdExtended = 0x2000'0000U;
inline constexpr std::uint32_t kCobIdIdentifier = 0x1FFF'FFFFU;  // bits 28..0 (11-bit identifiers: 10..0)

struct PdoParameters {
  std::uint32_t cob_id = 0;  // the whole 32-bit entry: bit 31 not valid, bit 30 no RTR, bit 29 29-bit
  std::uint8_t transmission_type = 1;
  std::uint16_t inhibit_time = 0;  // 100 µs
  std::uint16_t event_timer = 0;   // ms
  std::vector<PdoEntry> mapping;   // sub 1 .. sub 0

  bool valid() const { return (cob_id & kCobIdNotValid) == 0; }
  bool extended() const { return (cob_id & kCobIdExtended) != 0; }
  std::uint32_t can_id() const { return cob_id & (extended() ? kCobIdIdentifier : 0x7FFU); }
  friend bool operator==(const PdoParameters&, const PdoParameters&) = default;
};

// One PDO as the master will decode and send it, with what the device profile lets it write.
struct PdoSpec {
  std::string name;                       // tpdo1, rpdo1, ...
  bool transmit = true;                   // a TPDO: the device sends it
  std::uint16_t communication_index = 0;  // 1400h../1800h..
  std::uint16_t mapping_index = 0;        // 1600h../1A00h..
  PdoParameters wanted;
  // False where the profile lets the device start the PDO valid or not and the line does not say:
  // the device's bit 31 is then taken as it is.
  bool validity_given = true;
  // The profile makes the PDO optional: a device without it (no 1400h../1800h.. object) is fine,
  // and the PDO is then not used.
  bool optional = false;
  PdoRules rules;
};

// A PDO as the boot left it: what the master decodes and sends by until the next boot.
struct PdoInUse {
  std::string name;
  PdoParameters parameters;
  bool adopted = false;  // taken from the device (adopt mode) rather than the line's
};

// What a device holds, as read: the optional entries it lacks are absent.
struct DevicePdo {
  bool absent = false;  // an optional PDO the device does not implement
  PdoParameters parameters;
  bool has_inhibit_time = true;
  bool has_event_timer = true;
  // Entries beyond sub 0 that the device has (read to know whether sub 0 alone can map them).
  std::vector<PdoEntry> unmapped;
};

// The first difference the master may not write: which entry, both values, and why not.
struct PdoMismatch {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::string expected;
  std::string actual;
  std::string message;
};

struct PdoWrite {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  unsigned bits = 8;  // 8, 16 or 32: the entry's UNSIGNEDn
  std::uint32_t value = 0;
};

struct PdoPlan {
  std::vector<PdoWrite> writes;        // in CiA 301 order; empty when the device already matches
  PdoParameters result;                // what the device holds once they are done (to read back)
  bool needs_not_operational = false;  // a mapping change: the device must not be operational
  // The first change that takes the PDO out of service while it is written (CiA 301 lets it
  // change only while the PDO is not valid: another identifier, the inhibit time, the mapping),
  // with both values; nullopt when the writes are only what a master may write to a valid PDO of
  // a running device (transmission type, event timer, the valid bit itself).
  std::optional<PdoMismatch> disrupts;
};

// What the boot does with a device it finds operational (it started itself, or only the line PC
// restarted) whose PDO parameters must change (README, "Start-up and recovery policy").
enum class PdoChangeWhenRunning {
  pre_operational,  // NMT enter pre-operational, write and read back, then the boot goes on to its start
  keep_running,     // left running: what needs the PDO not valid is not written (boot error J, once)
};

// The writes from `device` to `spec.wanted`, or the first difference the profile fixes.
Result<PdoPlan, PdoMismatch> plan_pdo(const PdoSpec& spec, const DevicePdo& device);

// `spec` with the device's own mapping and transmission parameters taken as wanted (adopt mode):
// only the COB-ID stays the master's.
PdoSpec adopt_device_pdo(const PdoSpec& spec, const DevicePdo& device);

// The differences between what was planned and what reads back, or empty.
std::optional<PdoMismatch> verify_pdo(const PdoSpec& spec, const PdoParameters& planned, const DevicePdo& read_back);

// "1A00h sub 2" style names and values for messages.
std::string describe_cob_id(std::uint32_t entry);
std::string describe_entry(PdoEntry entry);

}  // namespace lb::canopen
