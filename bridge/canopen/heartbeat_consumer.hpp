#pragma once
// Supervises one remote node's heartbeat (CiA 301 1016h): its NMT state, boot-ups, and whether
// it is still alive within the configured timeout.

#include <chrono>
#include <cstdint>
#include <functional>

#include "canopen/bus_loop.hpp"
#include "canopen/nmt.hpp"

namespace lb::canopen {

class HeartbeatConsumer {
 public:
  struct Listener {
    std::function<void()> on_boot_up;                              // the node (re)booted
    std::function<void(NmtState state, bool online)> on_change;    // state or online flag changed
    std::function<void(NmtState state)> on_heartbeat;              // every heartbeat, after on_change
    std::function<void(const can::CanFrame& frame)> on_malformed;  // a frame on 700h + n without data
  };

  HeartbeatConsumer(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds timeout, Listener listener);

  std::uint8_t node_id() const { return node_id_; }
  NmtState state() const { return state_; }
  bool online() const { return online_; }
  std::int64_t last_heartbeat_ns() const { return last_heartbeat_ns_; }

 private:
  void on_frame(const can::CanFrame& frame);
  void on_timeout();

  BusLoop& loop_;
  std::uint8_t node_id_;
  std::chrono::milliseconds timeout_;
  Listener listener_;
  BusLoop::TimerId timer_;
  NmtState state_ = NmtState::unknown;
  bool online_ = false;
  std::int64_t last_heartbeat_ns_ = 0;
};

}  // namespace lb::canopen
