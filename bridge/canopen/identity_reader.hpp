#pragma once
// What a device says about itself, read by SDO uploads only (CiA 301: 1000h device type, 1018h
// sub 1..4 identity, 1008h/1009h/100Ah names, 1017h heartbeat producer time), and judged against
// what the line expects at its node-ID (CiA 302-2 1F84h..1F88h: errors B, C, D, M, N, O). The one
// owner of that reading and that judgement, for both who need it: a boot's identity step and its
// names read for the record (BootSequence), and a device adopted as it runs when a standby takes
// the bus over (NodeStateMachine::take_over), which must never be written to. It writes nothing,
// ever: a reader that cannot download cannot reconfigure an adopted device by mistake.
//
// Every read is asynchronous on the bus loop through the bus's SdoClient, like every other SDO
// transfer, so a device that does not answer delays nobody else, nor SYNC.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "canopen/sdo_client.hpp"

namespace lb::canopen {

struct DeviceIdentity {
  std::uint32_t device_type = 0;
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision_number = 0;
  std::uint32_t serial_number = 0;
  std::string device_name;
  std::string hardware_version;
  std::string software_version;
  std::string remarks;  // optional objects the device did not provide
  std::int64_t read_at_ns = 0;
};

// What the device at a node-ID must be (CiA 302-2 1F84h..1F88h): 1000h bits 0..15 always, each
// other value where it is given.
struct ExpectedIdentity {
  std::uint16_t profile_number = 0;
  std::optional<std::uint32_t> device_type;
  std::optional<std::uint32_t> vendor_id;
  std::optional<std::uint32_t> product_code;
  std::optional<std::uint32_t> revision;
  std::optional<std::uint32_t> serial_number;
};

// Why a boot failed, in CiA 302-2 terms: B no answer to 1000h, C device type, D vendor-ID,
// M product code, N revision, O serial number, J configuration download, K no heartbeat.
struct BootError {
  char code = 0;
  std::string step;  // "device type", "identity", "PDO configuration", "configuration", "heartbeat"
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::string expected;
  std::string actual;
  std::uint32_t abort_code = 0;
  std::string message;  // the whole story in one line
};
// The letters a boot of this bridge reports (of CiA 302-2's A..O): diagnostics give a count for
// each, zero or not, so a counter exists before its first failure.
inline constexpr std::string_view kBootErrorLetters = "BCDJKMNO";

class IdentityReader {
 public:
  // Asked before every request and before the answer: true ends the reading silently.
  using Cancelled = std::function<bool()>;

  // 1000h and 1018h sub 1..4 as read and judged.
  struct Check {
    DeviceIdentity identity;  // what was read (0 where not)
    // The first value that is not what the line expects (C, D, M, N, O), or that could not be read
    // (B: no answer to 1000h; D, M, N, O: 1018h sub 1..4 refused other than as absent). A boot fails
    // with it.
    std::optional<BootError> error;
    // Every value was read: `error`, if any, is the device's answer (a device other than the line
    // configures there), not a read that failed.
    bool answered = false;
  };
  // Everything a device says about itself: the check, then (when it answered) the names and 1017h.
  struct Reading {
    Check check;                                         // check.identity holds the names and the remarks too
    std::optional<std::uint16_t> heartbeat_producer_ms;  // 1017h; nullopt: absent or not read (a remark says which)
  };

  IdentityReader(SdoClient& sdo, std::uint8_t node, const ExpectedIdentity& expected);

  // Loop thread. The boot's identity step: 1000h and 1018h sub 1..4, judged. `done` follows once
  // unless cancelled.
  void check(Cancelled cancelled, std::function<void(Check)> done) const;
  // Loop thread. 1008h, 1009h and 100Ah into `identity`, each read whatever became of the one before
  // (an abort of an optional object is a remark in identity.remarks, not an error; after a
  // timeout the rest is not asked); stamps identity.read_at_ns. `done` follows once unless cancelled.
  void read_names(DeviceIdentity identity, Cancelled cancelled, std::function<void(DeviceIdentity)> done) const;
  // Loop thread. check(), then, when the device answered it (whether or not it is what the line
  // expects), read_names() and 1017h. `done` follows once unless cancelled.
  void read_all(const Cancelled& cancelled, std::function<void(Reading)> done) const;

  const ExpectedIdentity& expected() const { return expected_; }

 private:
  SdoClient& sdo_;
  std::uint8_t node_;
  ExpectedIdentity expected_;
};

}  // namespace lb::canopen
