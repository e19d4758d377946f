#pragma once
// The master's view of one device: heartbeat supervision plus, in the master role, NMT start at
// start-up and after every boot-up (a device that reboots mid-run is put back to work).

#include <chrono>
#include <cstdint>
#include <functional>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/heartbeat_consumer.hpp"
#include "canopen/nmt.hpp"

namespace lb::canopen {

class RemoteNode {
 public:
  using ChangeListener = std::function<void(NmtState state, bool online)>;

  // may_transmit = false for the monitor role: the node is observed, never commanded.
  RemoteNode(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_timeout, bool may_transmit);

  void on_change(ChangeListener listener) { listeners_.push_back(std::move(listener)); }  // before start
  void start();  // loop thread: the first NMT start

  std::uint8_t node_id() const { return heartbeat_.node_id(); }
  NmtState state() const { return heartbeat_.state(); }
  bool online() const { return heartbeat_.online(); }
  // Started by this bridge and alive: the condition for sending it RPDOs.
  bool ready_for_pdos() const { return started_ && online() && state() == NmtState::operational; }

 private:
  void send_start();
  void changed(NmtState state, bool online);

  BusLoop& loop_;
  bool may_transmit_;
  bool started_ = false;
  std::vector<ChangeListener> listeners_;
  HeartbeatConsumer heartbeat_;
};

}  // namespace lb::canopen
