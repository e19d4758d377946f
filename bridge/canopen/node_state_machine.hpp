#pragma once
// The master's one owner of a remote node's state (CiA 302-2 error control and boot, master
// role): it hears the node (RemoteNode: heartbeat, boot-up, states not commanded), runs its boot
// (BootSequence), sends what NMT the master decides, keeps an operator's commands, and holds the
// result as one explicit NodeState. Every transition is logged once and told to the node's
// drivers (NodeDriver::on_state).
//
// When a device is booted: at start-up, after every believed boot-up, and whenever the master no
// longer knows what its object dictionary holds: its heartbeat came back after a loss, or it
// reports a state it was not told to take (it may have been reset without its boot-up reaching
// the master, e.g. during a bus-off). Never a bare NMT start of such a device: it is booted again
// (CiA 302-2 "boot slave"), or reset so that its boot-up starts the boot, as the line configures.
// A reset always leads to a boot (bounded wait for the boot-up), and one reset is all an incident
// gets: until the boot after a reset has passed, a further state-unknown event (the device back
// after the silence of a slow reset, a state not commanded) boots it instead of resetting it
// again, so a device whose reset outlasts its heartbeat timeout is not reset in a loop. A device
// that fails its boot is tried again after the retry interval, unless it runs (then it is left
// running and reported); one that keeps booting (a boot-up storm) is reported and backed off.
//
// A device whose heartbeat stops while it is still heard by other frames of its own (RemoteNode::
// on_heartbeat_missing) keeps its state here (it is not lost: it runs, and it takes a stop) while
// its heartbeat producer time 1017h is read and, if it changed under the bridge, written back
// (BootSequence::check_heartbeat_producer; counted in heartbeat_producer_rewrites). Without its
// heartbeat one timeout after that, or when 1017h was not the cause, it is lost as any other.
//
//   unknown ──heard──▶ booting ──passed, heard operational──▶ operational
//      │                 │  ▲ └──failed──▶ boot failed ──retry──┘ │      │
//      │                 │  │ └──failed while it runs──▶ running unmanaged
//      │                 │  └──boot-up, state not commanded, back after loss──┐
//      │                 └──held by an operator──▶ stopped by operator ◀──operator stop
//      └── any state ──heartbeat lost──▶ lost;  operator/recovery reset ──▶ resetting ──▶ booting

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <string_view>

#include "base/repeat_log.hpp"
#include "base/result.hpp"
#include "canopen/boot_sequence.hpp"
#include "canopen/node_driver.hpp"
#include "canopen/node_state.hpp"
#include "canopen/remote_node.hpp"
#include "canopen/sdo_client.hpp"

namespace lb::canopen {

enum class RecoveryAction { reboot, reset_node };

class NodeStateMachine final : public NodeDriver {
 public:
  struct Settings {
    RecoveryAction on_state_unknown = RecoveryAction::reboot;
    std::chrono::milliseconds retry{5000};  // after a failed boot
    // A storm: this many boot-ups or lost states within the window. Each further one doubles the
    // wait before the next boot, up to max_backoff.
    unsigned storm_count = 5;
    std::chrono::milliseconds storm_window{60000};
    std::chrono::milliseconds max_backoff{300000};
    // After an NMT reset: how long to wait for the boot-up before booting anyway.
    std::chrono::milliseconds reset_bound{2000};
  };
  struct Counters {
    std::uint32_t boots = 0;          // attempts begun
    std::uint32_t boots_started = 0;  // attempts that ended with NMT start
    std::uint32_t boot_failures = 0;
    // Of boot_failures: per CiA 302-2 letter, A..O (index: letter - 'A'); a failure without one
    // (none so far) is in boot_failures only.
    std::array<std::uint32_t, 15> boot_failures_by_letter{};
    std::uint32_t state_unknown = 0;  // lost-and-back and unexpected states
    std::uint32_t storms = 0;         // times a storm began
    std::uint32_t transitions = 0;    // changes of state()
    // Its heartbeat producer time 1017h was found changed under the bridge (its heartbeat stopped
    // while it was heard) and written back.
    std::uint32_t heartbeat_producer_rewrites = 0;
    // A state-unknown event while the boot after a reset had not passed: booted, not reset again.
    std::uint32_t resets_spared = 0;
    std::uint32_t adopted = 0;  // adopted as it ran when a standby took the bus over
    // Adopted devices whose identity, read after the takeover, is not what the line expects (left running).
    std::uint32_t adopted_identity_mismatches = 0;
  };

  // Before the loop starts: attaches itself to the node (as its first driver, so that it acts on
  // an event before the gateways hear of the state it leads to).
  NodeStateMachine(BusLoop& loop, RemoteNode& node, SdoClient& sdo, BootSequence::Settings boot, Settings settings);
  NodeStateMachine(const NodeStateMachine&) = delete;
  NodeStateMachine& operator=(const NodeStateMachine&) = delete;

  void start();  // loop thread: the first boot
  // Loop thread, instead of start() on a standby that took the bus over (docs/redundancy.md): a
  // device heard operational is adopted as it runs, without a frame (no NMT, no SDO download); one
  // the master before held stopped or pre-operational (its last NMT command, and the device reports
  // that state) is adopted held so; any other gets the normal boot.
  // An adopted device is then read, never written: what it says about itself (IdentityReader:
  // 1000h, 1018h, 1008h..100Ah, 1017h, by SDO uploads) is judged against the line's expected
  // identity and told to the drivers as a BootReport with `adopted` set (NodeDriver::on_boot), as a
  // boot's would be. The reading begins right after the first SYNC this bridge sends (on_sync; it
  // is posted behind that cycle, so none of its frames goes out ahead of that SYNC or its RPDOs),
  // and for a device held stopped (which answers no SDO, CiA 301) once it is heard in another
  // state. An identity the line does not expect leaves the device running (stopping a running
  // line for what the master before accepted would be worse): a warning, the report's warnings and
  // detail() say it. A boot that begins meanwhile abandons the reading.
  void take_over(std::optional<NmtCommand> last_command);

  // Loop thread: an operator's NMT command. Start is refused for a device whose boot has not
  // passed (its boot starts it); a stop or pre-operational is kept until an operator starts or
  // resets the device, across heartbeat losses and boot-ups; a reset leads to a boot and ends a
  // boot-up storm's back-off (a deliberate action).
  Result<void> operator_command(NmtCommand command);

  NodeState state() const { return state_; }
  // Loop thread: what diagnostics show next to the state (the boot's step, a pending retry, a storm).
  std::string detail() const;
  const BootReport& report() const { return boot_.report(); }
  const Counters& counters() const { return counters_; }

  // NodeDriver, told by the node.
  void on_event(NodeEvent event) noexcept override;
  void on_heartbeat(NmtState state) noexcept override;
  void on_command(NmtCommand command) noexcept override;
  void on_sync() noexcept override;

 private:
  void enter(NodeState next, std::string_view why);
  NodeState silent_state() const;  // what a node not heard now is: unknown, or lost
  void reset_sent(bool by_operator);
  bool boot_under_way() const;
  void recover(const char* why);
  void boot_now(const std::string& why);
  void boot_after(std::chrono::milliseconds delay, const std::string& why);
  // Records a boot-up or lost state; true (and the delay armed) when it makes a storm.
  bool storm();
  void finished(const BootReport& report);
  void count_failure(const BootReport& report);
  void keep_hold();                 // a failed boot of a held device: the hold's NMT command all the same
  void check_heartbeat_producer();  // RemoteNode::on_heartbeat_missing
  void abandon_heartbeat_check();   // a boot or a reset begins
  void read_adopted();              // what an adopted device says about itself (take_over)
  void adopted_read(IdentityReader::Reading reading);
  void abandon_adoption();  // a boot or a reset begins: the adoption is history

  BusLoop& loop_;
  RemoteNode& node_;
  BootSequence boot_;
  Settings settings_;
  NodeState state_ = NodeState::unknown;
  bool started_ = false;  // start() was called: events before it are the start-up boot's
  BusLoop::TimerId timer_;
  BusLoop::TimerId reset_timer_;  // bounds the wait for the boot-up after a reset
  std::deque<std::chrono::steady_clock::time_point> recent_;
  std::chrono::milliseconds backoff_{0};
  std::string waiting_;  // why the next boot is pending, or empty
  // The last boot's failure until a boot passes: a retry under way does not hide why the device is
  // not started (an NMT start refused during it names it).
  std::optional<BootError> last_failure_;
  RepeatLog boot_log_;  // an absent device is tried every retry interval: the same line once a minute
  // An NMT reset was sent (recovery or operator) and no boot has passed since: a further
  // state-unknown event boots the device instead of resetting it again.
  bool reset_unconfirmed_ = false;
  bool checking_heartbeat_producer_ = false;
  // The reading of a device adopted at a takeover (take_over), until a boot begins.
  enum class Adoption {
    none,            // not adopted, or booted since
    awaiting_sync,   // adopted: read after the first SYNC
    awaiting_state,  // adopted held stopped: read once it is heard in a state that answers SDO
    reading,         // its identity, names and 1017h are being read
    read,            // read (detail() says what was found)
  };
  Adoption adoption_ = Adoption::none;
  std::uint64_t adoption_generation_ = 0;  // a new reading or a boot makes the old one's callbacks no-ops
  std::string adoption_detail_;            // what detail() says of the adoption
  Counters counters_;
};

}  // namespace lb::canopen
