#pragma once
// CiA 302-2 flying master on a standby bus (docs/redundancy.md): which of the bus's masters masters
// it, negotiated on 71h-76h, which no device acts on (BusLoop::send_negotiation: sent while the
// standby holds every other transmission).
//
// Power-up: listen for the negotiation delay, ask (73h), wait the detection timeout. An active master
// answering (71h [priority, node-ID]), or the line's master heartbeat heard: stand by it (the
// ActiveMasterWatch takes over when its heartbeat is silent). Nobody: request a negotiation (72h) and
// wait priority x priority slot + node-ID x device slot; a better master's 71h meanwhile (lower
// priority, then lower node-ID): stand by it; the wait over: this bridge masters the bus.
//
// Active: answers 73h with 71h, sends 76h every detection cycle, so that two active masters find
// each other. Evidence of another active master (a 76h, a 72h, another's 71h, a heartbeat on the
// line's master node-ID, which this bridge produces) makes it negotiate again while it goes on
// mastering; a better master's 71h then makes it step back. A master whose loop was stalled (its
// process stopped) past two of its heartbeat periods, and that then reads another master's frames
// stamped during the stall (or less than a stall after it), steps back at once: a standby has taken
// over meanwhile, and mastership never goes back by itself.
//
// A standby watching a live master takes no part in a negotiation: mastership moves only when the
// master dies or by an operator.

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

#include "base/log_rate.hpp"
#include "canopen/bus_loop.hpp"

namespace lb::canopen {

class OtherMasterWatch;

class FlyingMaster {
 public:
  struct Settings {
    std::uint8_t node_id = 0;  // the line's master node-ID: this bridge's in the negotiation
    std::uint8_t priority = 0;
    std::chrono::milliseconds detect_timeout{100};
    std::chrono::milliseconds negotiation_delay{500};
    std::chrono::milliseconds priority_slot{1500};
    std::chrono::milliseconds device_slot{10};
    std::chrono::milliseconds detect_cycle{4000};
    std::chrono::milliseconds stall{100};  // a loop stall this long: a standby may have taken over
  };
  struct Callbacks {
    std::function<void()> win;                              // no master was active: master the bus
    std::function<void(std::uint8_t node)> stand_by;        // an active master (node): stand by it
    std::function<void(const std::string& why)> step_back;  // another master won: stop mastering
  };
  enum class State { detecting, standing_by, negotiating, active, stepped_back };

  // Before the loop starts. other: the bus's watch on other masters, silenced while a negotiation
  // decides (it would otherwise yield to the very master being negotiated with); may be null.
  FlyingMaster(BusLoop& loop, Settings settings, OtherMasterWatch* other, Callbacks callbacks);
  FlyingMaster(const FlyingMaster&) = delete;
  FlyingMaster& operator=(const FlyingMaster&) = delete;

  // Loop thread from here on.
  void start();      // power-up detection
  void mastering();  // this bridge masters the bus from now on (won, or took over): it says so (71h)
  State state() const { return state_; }
  // The negotiation's state and its last event, in words (diagnostics).
  std::string describe() const;

 private:
  void answer_seen(const can::CanFrame& frame);
  void request_seen();
  void active_request_seen();
  void force_seen();
  void master_heartbeat_seen(const can::CanFrame& frame);
  void detection_step();
  void negotiate(bool request);
  void waited();
  void stand_by(std::uint8_t node);
  void step_back(const std::string& why);
  void announce();
  void tick();
  bool better(std::uint8_t priority, std::uint8_t node) const;
  bool stalled_at(std::int64_t stamp_ns) const;
  void event(std::string text);

  BusLoop& loop_;
  Settings settings_;
  OtherMasterWatch* other_;
  Callbacks callbacks_;
  BusLoop::TimerId wait_timer_;
  BusLoop::TimerId cycle_timer_;
  BusLoop::TimerId tick_timer_;
  State state_ = State::detecting;
  bool asked_ = false;       // power-up: the 73h went out
  bool was_active_ = false;  // the negotiation running began while this bridge mastered the bus
  std::uint8_t active_node_ = 0;
  std::int64_t last_tick_ns_ = 0;
  std::int64_t stall_from_ns_ = 0;  // the last stall of this loop (realtime), 0: none
  std::int64_t stall_to_ns_ = 0;
  std::string last_event_;
  LogRate log_{2};
};

std::string_view to_string(FlyingMaster::State state);

}  // namespace lb::canopen
