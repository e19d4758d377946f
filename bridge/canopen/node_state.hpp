#pragma once
// The master's view of one remote node, as one explicit state (NodeStateMachine owns it).

#include <string_view>

namespace lb::canopen {

enum class NodeState {
  unknown,              // not heard since the bridge started
  booting,              // a boot is checking and configuring it
  boot_failed,          // the last boot failed (or a boot-up storm backs it off): retried later
  running_unmanaged,    // its boot failed while it runs: left running, reported, not started by the bridge
  operational,          // booted and started by the bridge
  stopped_by_operator,  // booted, then kept in an operator's NMT stop or pre-operational
  resetting,            // an NMT reset was sent: waiting (bounded) for its boot-up
  lost,                 // no heartbeat within its timeout
};

std::string_view to_string(NodeState state);

}  // namespace lb::canopen
