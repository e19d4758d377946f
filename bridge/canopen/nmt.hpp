#pragma once
// NMT commands and states (CiA 301 network management).

#include <cstdint>
#include <string_view>

#include "can/can_frame.hpp"
#include "canopen/cob_id.hpp"

namespace lb::canopen {

enum class NmtCommand : std::uint8_t {
  start = 0x01,
  stop = 0x02,
  enter_pre_operational = 0x80,
  reset_node = 0x81,
  reset_communication = 0x82,
};

// Values as a device reports them in its heartbeat byte 0 (toggle bit masked off).
enum class NmtState : std::uint8_t {
  boot_up = 0x00,
  stopped = 0x04,
  operational = 0x05,
  pre_operational = 0x7F,
  unknown = 0xFF,  // not yet heard from; never on the wire
};

constexpr std::string_view to_string(NmtState s) {
  switch (s) {
    case NmtState::boot_up: return "boot-up";
    case NmtState::stopped: return "stopped";
    case NmtState::operational: return "operational";
    case NmtState::pre_operational: return "pre-operational";
    case NmtState::unknown: break;
  }
  return "unknown";
}

// Maps a heartbeat/boot-up byte to a state; anything not defined by CiA 301 is `unknown`.
constexpr NmtState nmt_state_from_byte(std::uint8_t b) {
  switch (b & 0x7F) {
    case 0x00: return NmtState::boot_up;
    case 0x04: return NmtState::stopped;
    case 0x05: return NmtState::operational;
    case 0x7F: return NmtState::pre_operational;
    default: return NmtState::unknown;
  }
}

// node_id 0 addresses all nodes.
inline can::CanFrame make_nmt_command(NmtCommand command, std::uint8_t node_id) {
  return can::make_frame(cob::nmt, {static_cast<std::uint8_t>(command), node_id});
}

inline can::CanFrame make_heartbeat(std::uint8_t node_id, NmtState state) {
  return can::make_frame(cob::heartbeat_base + node_id, {static_cast<std::uint8_t>(state)});
}

}  // namespace lb::canopen
