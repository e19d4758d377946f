#pragma once
// When a PDO goes on the bus, by its CiA 301 transmission type:
//   1..240   synchronous, after every n-th SYNC;
//   0        synchronous acyclic: after a SYNC, only when its data changed;
//   252/253  on remote request only: never spontaneously (RTR is not served here);
//   254/255  event-driven: when its data changes, no sooner than the inhibit time after the
//            previous one, and again whenever the event timer expires.
// The same logic sends the bridge's RPDOs (master role) and the simulators' TPDOs.

#include <chrono>
#include <cstdint>
#include <functional>

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
  // Fills the data of a frame (len and bytes) from the current image.
  using Pack = std::function<void(can::CanFrame&)>;
  // Whether the PDO may go out now (e.g. the device is started); counted when it did.
  using Gate = std::function<bool()>;
  using Sent = std::function<void()>;

  // Before the loop starts or on the loop thread.
  PdoTransmitter(BusLoop& loop, Settings settings, Pack pack, Gate may_send, Sent sent = {});

  void on_sync();  // a SYNC went out (master) or came in (device)
  void on_data();  // the image may have changed: event-driven and acyclic types look
  void resend();   // forget what was sent: the next trigger sends even unchanged data
  // Loop thread: a new identifier, type or timing (a device's PDO parameters written, a mapping
  // adopted at boot). The SYNC count restarts, timers stop and what was sent is forgotten.
  void reconfigure(Settings settings);
  const Settings& settings() const { return settings_; }

 private:
  bool data_changed();
  void send();
  void send_when_inhibit_allows();

  BusLoop& loop_;
  Settings settings_;
  Pack pack_;
  Gate may_send_;
  Sent sent_;
  BusLoop::TimerId inhibit_timer_;
  BusLoop::TimerId event_timer_;
  unsigned sync_count_ = 0;
  bool pending_ = false;
  bool have_last_ = false;
  can::CanFrame last_;
  std::chrono::steady_clock::time_point last_sent_{};
};

}  // namespace lb::canopen
