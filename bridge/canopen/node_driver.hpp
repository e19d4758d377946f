#pragma once
// The one interface through which a device's gateways hear about their node, in the spirit of
// Lely's DriverBase. Every hook runs on the bus loop thread and cannot throw: a gateway that
// cannot handle something reports it itself, and nothing it does can stop the node's supervision
// or the bus's SYNC. A hook must not block (no disk, no waiting for DDS).

#include <array>
#include <cstdint>
#include <optional>
#include <span>

#include "base/result.hpp"
#include "canopen/emcy.hpp"
#include "canopen/nmt.hpp"
#include "canopen/node_state.hpp"
#include "canopen/pdo_parameters.hpp"

namespace lb::canopen {

struct BootReport;

// What a boot found, told right before it sends NMT start (the last moment to decide what the
// device's first RPDO carries).
struct StartFacts {
  bool found_operational = false;  // it reported operational when the boot began
  // The boot put it, found operational, in pre-operational to write its PDO parameters
  // (pdo_change_when_running: pre_operational): a pause, after which no enabling level comes back
  // by itself.
  bool paused_by_boot = false;
  std::array<std::uint32_t, 4> identity{};  // 1018h sub 1..4 as read (0 where absent)
  // A standby took the bus over and adopted the device as it runs (no boot, no NMT, no SDO): its
  // RPDOs carry what the master before put on the bus last, nothing else (docs/redundancy.md).
  bool adopted = false;
};

// What makes the master lose track of a device's object dictionary (master role only).
enum class NodeEvent {
  boot_up,           // a believed boot-up: the device starts from its power-on values
  lost,              // no heartbeat within the timeout
  returned,          // a heartbeat while it was offline (the first one, or again after a loss)
  unexpected_state,  // it reports a state the master did not command (pre-operational, stopped)
};
std::string_view to_string(NodeEvent event);

class NodeDriver {
 public:
  // The node state machine entered `state` (master role).
  virtual void on_state(NodeState /*state*/) noexcept {}
  // What makes the device's state unknown to the master (master role), before the state machine acts.
  virtual void on_event(NodeEvent /*event*/) noexcept {}
  // A boot attempt ended (master role), passed or failed; or, with report.adopted, the reading of a
  // device adopted at a takeover (no boot ran: NodeStateMachine::take_over).
  virtual void on_boot(const BootReport& /*report*/) noexcept {}
  // Configuration step of the boot: the PDOs the device will use from now on. A refusal fails the
  // boot (CiA 302-2 error J) and the device is not started.
  virtual Result<void> on_config(std::span<const PdoInUse> /*pdos*/) noexcept { return {}; }
  // Right before the boot sends NMT start.
  virtual void on_start(const StartFacts& /*facts*/) noexcept {}
  // An operator's or the line's hold on the node was set, changed or released (nullopt)
  // (RemoteNode::hold): what a restarted bridge must keep.
  virtual void on_hold(const std::optional<NmtCommand>& /*hold*/) noexcept {}
  // An NMT command went out to the node, whoever sent it (the boot, an operator, the line).
  virtual void on_command(NmtCommand /*command*/) noexcept {}
  // The state the device reports or its online flag changed (both roles).
  virtual void on_nmt_change(NmtState /*state*/, bool /*online*/) noexcept {}
  // Every heartbeat that carries a state (not a boot-up message), after the node took it.
  virtual void on_heartbeat(NmtState /*state*/) noexcept {}
  // An emergency (both roles), after the active-error list took it.
  virtual void on_emcy(const Emergency& /*emcy*/) noexcept {}
  // The active-error list changed other than by an EMCY (a boot-up, a reading from the device).
  virtual void on_errors() noexcept {}
  // The bus's SYNC went out (master role, when the bus produces SYNC).
  virtual void on_sync() noexcept {}

 protected:
  NodeDriver() = default;
  NodeDriver(const NodeDriver&) = default;
  NodeDriver& operator=(const NodeDriver&) = default;
  ~NodeDriver() = default;  // drivers are not owned through this interface
};

}  // namespace lb::canopen
