#pragma once
// Mandatory devices of one master bus (the CiA 302-2 1F81h bit 3 idea): the line does not run
// without them.
//   - Start-up (CiA 302-2 network boot): no device of the bus is started before every mandatory
//     one passed its boot. The others are checked and configured as usual and then kept
//     pre-operational ("waiting for mandatory device X"); they are started as soon as the last
//     mandatory one passes. A device found operational (only the bridge restarted) is left running
//     while the mandatory ones are still booting: a restarted bridge does not stop a running line
//     because one boot is slower than another.
//   - While the line runs: a mandatory device lost (heartbeat) or failing its boot, with
//     when_mandatory_fails: stop_others (CiA 302-2 1F80h bit 6 "stop all"), makes every other
//     device the bridge started get NMT stop, kept like an operator's stop (RemoteNode::hold): its
//     boots put it back in stopped, and nothing restarts it by itself when the mandatory device
//     comes back; an operator's nmt start (or reset) releases it. With report_only: log and
//     diagnostics only (and the start-up wait applies only until the mandatory devices first passed).
//     That stop outlives the bridge (HoldKeeper keeps it in the state directory): a restarted
//     bridge puts it back before its loop starts (kept_stop), and it is held as before.
//   - On a standby bus (docs/redundancy.md): nothing while it stands by (the master of the moment
//     judges the line). From the takeover on the line's state is the bus's, told through the same
//     hooks as a start-up: a mandatory device adopted as it runs has passed (the master before
//     booted it), one that gets a boot is missing until it passes; a device adopted running is
//     left running as one found operational at a restart (a takeover stops nothing), the others
//     wait, and a mandatory boot that fails is handled by when_mandatory_fails as always.
// A held device still takes every stopping command: NMT stop, pre-operational and reset are the
// operator's as for any device, and set values that enable nothing are accepted (the device is
// stopped, so its RPDOs wait for an operator's start).
//
// It hears each member as one of its node's drivers (NodeDriver: on_start, right before the boot
// decides between NMT start and the hold, the last moment to hold it; on_event; on_boot), acts
// through RemoteNode's hold and command, and is told operator commands by the device services. Everything runs on the
// bus's loop thread (the diagnostics snapshot included): no locks.

#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/boot_sequence.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/node_driver.hpp"
#include "canopen/remote_node.hpp"
#include "gateways/persistence/hold_keeper.hpp"
#include "gateways/persistence/kept_holds.hpp"
#include "profiles/line_config.hpp"

namespace lb::gateways {

class MandatoryDevices {
 public:
  using Policy = profiles::StartupPolicy::WhenMandatoryFails;
  struct Member {
    std::string name;
    canopen::RemoteNode* node = nullptr;
    bool mandatory = false;
    // Its boot is checking and configuring it right now: an NMT stop would make the boot's SDO
    // requests go unanswered, so it is only held (the boot ends by stopping it).
    std::function<bool()> booting;
  };

  // Before the loop starts (registers on the members' nodes). At least one member is mandatory.
  MandatoryDevices(canopen::BusLoop& loop, std::string bus, Policy policy, std::vector<Member> members);
  MandatoryDevices(const MandatoryDevices&) = delete;
  MandatoryDevices& operator=(const MandatoryDevices&) = delete;

  // Before the loop starts, on a standby bus: nothing the bus shows counts until mastering() (a
  // mandatory device lost while another master runs the line is that master's to act on).
  void stand_by() { standing_by_ = true; }
  // Loop thread, on a standby bus that is mastered from now on (its takeover, or no master heard),
  // before its devices are adopted or booted: the line is judged from here on, as after a start.
  void mastering();

  // Loop thread, from the device services: an operator's NMT command was sent to member i. From
  // then on its state is the operator's (a start releases what this class held).
  void operator_command(std::size_t i, canopen::NmtCommand command);
  // Before the loop starts: member i's stop by the line, kept from before the bridge restarted
  // (HoldKeeper::restore). Held as any stop of the line: only an operator's start or reset
  // releases it, whatever the mandatory devices do meanwhile.
  void kept_stop(std::size_t i, const KeptHold& hold);
  // Loop thread: what the line holds member i in (HoldKeeper's line view).
  HoldKeeper::LineHold line_hold(std::size_t i) const;

  // Loop thread, for diagnostics.
  std::vector<std::string> missing() const;  // mandatory devices that have not passed their boot (now)
  std::string state() const;                 // the line's situation in one line ("" when nothing to say)
  std::string hold_of(std::size_t i) const;  // why member i is held by the line ("" when it is not)
  // What diagnostics call member i's state while the line holds it ("" when it does not).
  std::string_view held_as(std::size_t i) const;
  bool mandatory(std::size_t i) const { return members_[i].mandatory; }
  Policy policy() const { return policy_; }

 private:
  enum class Presence { booting, passed, failed, lost };  // of a mandatory member, as the line sees it
  enum class Hold { none, waiting, stopped };             // what this class holds a member in
  struct Status {
    Presence presence = Presence::booting;
    Hold hold = Hold::none;
    bool started = false;           // the bridge started it (a boot, the gate, an operator) in this run
    std::string why;                // of a lost or failed mandatory member
    std::string hold_why;           // why this class holds it
    std::int64_t kept_since_s = 0;  // a stop kept from before the bridge restarted: since when (Unix s)
  };

  // What the line hears of member i through its node.
  class MemberDriver final : public canopen::NodeDriver {
   public:
    MemberDriver(MandatoryDevices& line, std::size_t i) : line_(line), i_(i) {}
    void on_start(const canopen::StartFacts& facts) noexcept override { line_.starting(i_, facts); }
    void on_event(canopen::NodeEvent event) noexcept override { line_.event(i_, event); }
    void on_boot(const canopen::BootReport& report) noexcept override { line_.boot_finished(i_, report); }

   private:
    MandatoryDevices& line_;
    std::size_t i_;
  };

  void starting(std::size_t i, const canopen::StartFacts& facts);
  void event(std::size_t i, canopen::NodeEvent event);
  // Every boot attempt of member i that ended.
  void boot_finished(std::size_t i, const canopen::BootReport& report);
  void gone(std::size_t i, Presence presence, std::string why);
  // The names of the mandatory members other than `except` that have not passed / that failed.
  std::string names_missing(std::size_t except) const;
  std::string names_failed(std::size_t except) const;
  bool waits(std::size_t i) const;  // member i may not be started now (a mandatory one missing)
  void stop_others(std::size_t failed);
  void open_gate();  // every mandatory one passed: the waiting members are started

  canopen::BusLoop& loop_;
  std::string bus_;
  Policy policy_;
  std::vector<Member> members_;
  std::vector<Status> status_;
  std::vector<std::unique_ptr<MemberDriver>> drivers_;
  bool passed_once_ = false;  // every mandatory member passed at least once (report_only: no more waiting)
  bool gate_check_posted_ = false;
  bool standing_by_ = false;  // a standby bus not mastered yet
};

}  // namespace lb::gateways
