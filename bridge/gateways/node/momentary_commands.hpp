#pragma once
// Command bits of a control word that are pressed like a button (CiA 420-1: "set as long as the
// button is pressed, but not shorter than 100 ms"). What counts is the bus, not a timer: a bit
// stays set until the RPDOs that carried it span at least the hold time, measured from the first
// frame that carried it to the frame that clears it, then that frame clears it. A missed or late
// SYNC makes the pulse longer, never shorter; a pulse that cannot reach the bus (the device is not
// started, went offline, the bus refused the frame) is abandoned and answered as such.
//
// Times are taken where they bound the truth: the first frame's after the bus took it, the
// releasing frame's before it was packed, so any observer of the bus sees at least the hold time
// between them. With a 20 ms SYNC a pulse is 5 or 6 frames (100 or 120 ms), as the loop's
// wake-ups fall.
//
// Loop thread only. The gateway reports its RPDOs that carry the control word: before_frame()
// right before one is packed, frame_sent() when it went out, frame_not_sent() when one was due
// and did not.

#include <chrono>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/bus_loop.hpp"

namespace lb::gateways {

class MomentaryCommands {
 public:
  using Clock = std::chrono::steady_clock;
  // CiA 420-1: "not shorter than 100 ms".
  static constexpr std::chrono::milliseconds kHold{100};
  // How a press ended. on_bus: the bit was on the bus for at least the hold time (frames and held
  // say how long and in how many frames); otherwise message says why it was not, or not fully.
  struct Outcome {
    bool on_bus = false;
    unsigned frames = 0;               // RPDOs that carried the bit for this press
    std::chrono::nanoseconds held{0};  // from its first frame to the frame that cleared it
    std::string message;               // empty when nothing needs saying
  };
  using Done = std::function<void(const Outcome&)>;

  // set_bit writes one bit of the image; changed tells the RPDO transmitters (event-driven ones send
  // at once) and the status that the image changed. A pulse that no frame carries within `patience`
  // (a PDO sent every n-th SYNC, remote-only, a SYNC that stopped) is abandoned.
  MomentaryCommands(canopen::BusLoop& loop, std::function<void(unsigned bit, bool on)> set_bit,
                    std::function<void()> changed, std::chrono::milliseconds hold = kHold,
                    std::chrono::milliseconds patience = std::chrono::seconds(2));
  MomentaryCommands(const MomentaryCommands&) = delete;
  MomentaryCommands& operator=(const MomentaryCommands&) = delete;

  // Sets the bit; done runs once, when the frame that releases it went out or the pulse could not
  // reach the bus. Pressing again while held extends the hold: the bit stays until this press too
  // has been on the bus for the hold time.
  void press(unsigned bit, Done done);
  bool held(unsigned bit) const;

  void before_frame();
  void frame_sent(Clock::time_point at);
  void frame_not_sent(std::string_view why);

 private:
  enum class State {
    waiting,    // set in the image, no frame carried it yet
    on,         // carried by at least one frame
    releasing,  // cleared in the image; the frame that clears it is not out yet
  };
  struct Press {
    Done done;
    std::optional<Clock::time_point> first;  // the first frame that carried the bit for it
    unsigned frames = 0;
  };
  struct Pulse {
    State state = State::waiting;
    std::vector<Press> presses;
    canopen::BusLoop::TimerId timer{};  // release, or give up waiting for a frame
    std::optional<Clock::time_point> last_frame;
  };

  Pulse& pulse(unsigned bit);
  // When every press of it has been on the bus for the hold time; nullopt while one has no frame.
  std::optional<Clock::time_point> release_due(const Pulse& p) const;
  void on_timer(unsigned bit);
  void release(unsigned bit, Pulse& p);
  void finish(unsigned bit, Pulse& p, Outcome base, std::optional<Clock::time_point> released_at);

  canopen::BusLoop& loop_;
  std::function<void(unsigned, bool)> set_bit_;
  std::function<void()> changed_;
  std::chrono::milliseconds hold_;
  std::chrono::milliseconds patience_;
  std::map<unsigned, Pulse> pulses_;
};

}  // namespace lb::gateways
