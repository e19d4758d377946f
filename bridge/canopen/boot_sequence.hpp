#pragma once
// Brings one device into service the CiA 302-2 way ("boot slave"), master role:
//   1. device type 1000h (is anyone there, and of the right profile?);
//   2. identity 1018h sub 1..4 against the expected values (steps 1 and 2: IdentityReader);
//   3. PDO configuration (then handed to the gateways): every PDO's communication and mapping parameters read and
//   compared with
//      what the master will decode and send; what differs is written in the CiA 301 order where
//      the profile lets a master write it, and read back; what differs where the profile fixes it
//      fails the boot (or, in adopt mode, the device's parameters are taken). A device found
//      operational whose PDOs must change is first put in pre-operational, or left running and
//      reported (J) without a write it would refuse (Settings::pdo_change_when_running);
//   4. the line's configuration writes, read back, then the heartbeat producer time 1017h;
//   5. a heartbeat from the device;
//   6. NMT start. Only now does the device count as configured and get RPDOs.
// Then it reads 1008h/1009h/100Ah for the record (IdentityReader). Each attempt ends with a report: started, or
// failed with the CiA 302-2 error letter, the object, both values and the abort code. When to
// boot (start-up, boot-up, lost state) is NodeStateMachine's decision. Every step is asynchronous on
// the bus loop, so a device that does not answer delays nobody else.

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "base/repeat_log.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/identity_reader.hpp"
#include "canopen/object_value.hpp"
#include "canopen/pdo_parameters.hpp"
#include "canopen/remote_node.hpp"
#include "canopen/sdo_batch.hpp"
#include "canopen/sdo_client.hpp"

namespace lb::canopen {

struct BootReport {
  bool started = false;
  std::optional<BootError> error;
  DeviceIdentity identity;
  std::optional<std::uint16_t> heartbeat_producer_ms;  // 1017h as the device has it after the boot
  std::vector<PdoInUse> pdos;
  std::vector<std::string> warnings;
  bool was_operational = false;  // CiA 302-2 L: it was running when the boot began
  // Configured, then put back in the state an operator's NMT stop or pre-operational left it in,
  // not started (RemoteNode::hold).
  bool held_by_operator = false;
  // Not a boot: a standby that took the bus over adopted the device as it ran and read what it says
  // about itself by SDO uploads only (NodeStateMachine::take_over). `started` tells that it runs as
  // the master before left it, `pdos` are the line's it adopted; an identity the line does not
  // expect is in `warnings`, never in `error` (no boot failed: the device runs on).
  bool adopted = false;
};

class BootSequence {
 public:
  struct Write {
    std::uint16_t index;
    std::uint8_t sub;
    DataType type;
    ObjectValue value;
    bool verify = true;  // read back after writing
  };
  struct Settings {
    ExpectedIdentity identity;
    std::vector<PdoSpec> pdos;
    bool adopt_device_pdos = false;
    // A device found operational (or not heard yet) whose PDO parameters must change.
    PdoChangeWhenRunning pdo_change_when_running = PdoChangeWhenRunning::pre_operational;
    std::vector<Write> writes;
    std::optional<std::uint16_t> heartbeat_producer_ms;  // written to 1017h when given
  };
  using Done = std::function<void(const BootReport&)>;

  // Before the loop starts or on the loop thread.
  BootSequence(BusLoop& loop, RemoteNode& node, SdoClient& sdo, Settings settings);
  BootSequence(const BootSequence&) = delete;
  BootSequence& operator=(const BootSequence&) = delete;

  // Loop thread. Starts an attempt, abandoning one that runs; `done` follows exactly once per
  // attempt that is not abandoned.
  void run(Done done);
  void cancel();  // abandons the running attempt silently
  bool running() const { return running_; }
  // The PDOs as the line configures them, as a boot that changed nothing leaves them in use: what a
  // standby that takes the bus over adopts a running device with (it verified their identifiers by
  // listening; it reads nothing from the device).
  std::vector<PdoInUse> line_pdos() const;
  const std::string& step() const { return step_; }
  const BootReport& report() const { return report_; }
  // What the boot reads and judges of the device's identity; also what reads an adopted device's.
  const IdentityReader& identity_reader() const { return identity_; }
  // Warnings about a device's heartbeat producer time 1017h against the node's heartbeat timeout
  // (no heartbeat at all, or a timeout too short for it), as a boot reports them.
  std::vector<std::string> heartbeat_warnings(std::optional<std::uint16_t> producer_ms) const;
  // What check_heartbeat_producer found.
  struct ProducerCheck {
    std::optional<std::uint16_t> expected;  // what the last boot that passed left in 1017h
    std::optional<std::uint16_t> found;     // what the device holds (nullopt: not read)
    bool written_back = false;              // it differed and now holds `expected` again
  };
  // Loop thread, between boots (the device configured): reads 1017h; when it differs from what
  // the last boot that passed left there (Settings::heartbeat_producer_ms, or the value that boot
  // read), writes that back, reads it back, and reports it (log error: both values). `done`
  // follows once, unless a boot begins meanwhile (the check is then abandoned silently).
  void check_heartbeat_producer(std::function<void(const ProducerCheck&)> done);
  // What the last boot that passed left in 1017h, as it read it (nullopt: not known).
  std::optional<std::uint16_t> heartbeat_producer_left() const { return producer_left_; }

  // Loop thread, told by the node state machine: a heartbeat (not a boot-up) arrived; the attempt
  // goes on if it waits for one. The heartbeat the boot waits for is one that follows the
  // configuration: a state, never the boot-up message (a device without a heartbeat producer
  // sends only that).
  void heard(NmtState state);

 private:
  using Replies = std::vector<SdoReply>;
  void batch(std::vector<SdoRequest> requests, std::function<void(Replies)> then);
  std::function<bool()> cancelled() const;  // the attempt under way was abandoned
  void read_pdos(const std::vector<PdoSpec>& specs, std::function<void(std::vector<DevicePdo>)> then);
  void configure_pdos(std::vector<DevicePdo> devices);
  void write_pdos();  // pdo_writes_, once the device's state is known (or its heartbeat timed out)
  void verify_pdos(const std::vector<PdoSpec>& specs, const std::vector<PdoParameters>& planned);
  void write_configuration();
  void verify_configuration();
  void use_pdos();
  void await_heartbeat();
  void start();
  void read_names();
  void fail(BootError error);
  void set_step(std::string step);

  BusLoop& loop_;
  RemoteNode& node_;
  SdoClient& sdo_;
  Settings settings_;
  IdentityReader identity_;
  Done done_;
  BusLoop::TimerId heartbeat_timer_;
  std::uint64_t generation_ = 0;  // a new attempt makes the callbacks of the old one no-ops
  bool running_ = false;
  bool waiting_for_heartbeat_ = false;
  // This attempt sent the device, found operational, to pre-operational to write its PDOs: it
  // still counts as found operational when it is started (RemoteNode::StartFacts).
  bool paused_running_ = false;
  bool waiting_for_state_ = false;  // a heartbeat before the PDO writes
  struct PdoWrites {
    std::vector<SdoRequest> writes;
    std::vector<PdoSpec> specs;           // the PDOs written, to read back
    std::vector<PdoParameters> planned;   // what they read back once written
    std::optional<PdoMismatch> disrupts;  // the first change a running device cannot take
  };
  PdoWrites pdo_writes_;
  std::string step_ = "waiting";
  BootReport report_;
  std::vector<PdoInUse> planned_pdos_;
  std::optional<std::uint16_t> producer_left_;  // 1017h as the last boot that passed read it
  RepeatLog fail_log_;                          // the same failure again (an absent device) once a minute
};

}  // namespace lb::canopen
