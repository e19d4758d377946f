#pragma once
// When a PDO goes on the bus, by its CiA 301 transmission type:
//   1..240   synchronous, after every n-th SYNC;
//   0        synchronous acyclic: after a SYNC, only when its data changed;
//   252/253  on remote request only: never spontaneously (RTR is not served here);
//   254/255  event-driven: when its data changes, no sooner than the inhibit time after the
//            previous one, and again whenever the event timer expires.
// The same logic sends the bridge's RPDOs (master role) and the simulators' TPDOs.
//
// A trigger that finds the PDO may not go out (its gate is closed, or the bus refuses the frame)
// sends nothing and says so (Hooks::not_sent); an event-driven PDO's event timer keeps running
// after such a refusal, so the PDO goes out again as soon as it may. The inhibit time counts from
// the last frame really sent, also for a resend (a device restarted, NMT, online again).

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>

#include "canopen/bus_loop.hpp"

namespace lb::canopen {

class PdoTransmitter {
 public:
  struct Settings {
    std::uint32_t can_id = 0;
    bool extended = false;
    std::uint8_t transmission_type = 1;
    std::chrono::microseconds inhibit{0};
    std::chrono::milliseconds event_timer{0};
  };
  enum class Refusal {
    gate,  // may_send said no (e.g. the device is not started)
    bus,   // the bus refused the frame (counted by the bus)
  };
  struct Hooks {
    // Fills the data of a frame (len and bytes) from the current image.
    std::function<void(can::CanFrame&)> pack;
    // Whether the PDO may go out now (e.g. the device is started).
    std::function<bool()> may_send;
    // Right before a frame that will be offered to the bus is packed: the last moment to change
    // the image for this very frame (a momentary command held long enough is released in it).
    std::function<void()> before_send = {};
    // The frame went out; `at` is taken right after the bus took it.
    std::function<void(const can::CanFrame& frame, std::chrono::steady_clock::time_point at)> sent = {};
    // A trigger came (SYNC, data change, event timer, inhibit time over) but nothing went out.
    std::function<void(Refusal why)> not_sent = {};
    // The frame about to go out carries a stop: it goes out as one (BusLoop::send_stop), through
    // another master's hold, so that a stop is held as long as it must be.
    std::function<bool()> stopping = {};
  };

  // Before the loop starts or on the loop thread.
  PdoTransmitter(BusLoop& loop, Settings settings, Hooks hooks);

  void on_sync();  // a SYNC went out (master) or came in (device)
  void on_data();  // the image may have changed: event-driven and acyclic types look
  void resend();   // forget what was sent: the next trigger sends even unchanged data
  // Loop thread: a frame that carries a stop, now, whatever the transmission type, the inhibit
  // time, the quiet time, the gate or another master's hold (BusLoop::send_stop): a synchronous
  // PDO sent between two SYNCs is taken by the device at the next SYNC, which is as soon as it can
  // act on it anyway. Only the bus can refuse it (then not_sent(bus) and the error). The frame
  // counts as sent for everything that follows (hooks, inhibit time, event timer).
  Result<void> send_now();
  // Loop thread: a new identifier, type or timing (a device's PDO parameters written, a mapping
  // adopted at boot). The SYNC count restarts, timers stop and what was sent is forgotten (the
  // inhibit time still counts from the last frame sent).
  void reconfigure(Settings settings);
  const Settings& settings() const { return settings_; }
  // Before the loop starts or on the loop thread: no frame of this PDO before `t`. A trigger
  // before then is held back, not refused: an event-driven PDO goes out at `t`, a synchronous one
  // at its first SYNC from `t` on. Survives reconfigure().
  void quiet_until(std::chrono::steady_clock::time_point t) {
    quiet_until_ = t;
    quiet_over_ = false;
  }

 private:
  bool data_changed();
  void send();
  bool held_back_quiet();
  void send_when_inhibit_allows();
  void refused(Refusal why);
  void arm_event_timer();

  BusLoop& loop_;
  Settings settings_;
  Hooks hooks_;
  BusLoop::TimerId inhibit_timer_;
  BusLoop::TimerId event_timer_;
  unsigned sync_count_ = 0;
  bool pending_ = false;
  bool owed_ = false;  // a synchronous PDO held back by quiet_until_: its next SYNC sends it
  std::chrono::steady_clock::time_point quiet_until_{};
  bool quiet_over_ = false;
  bool have_last_ = false;
  can::CanFrame last_;
  std::optional<std::chrono::steady_clock::time_point> last_sent_;
};

}  // namespace lb::canopen
