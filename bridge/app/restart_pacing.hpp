#pragma once
// How soon a DDS process is started again after one ended (docs/bus-isolation.md "Supervision"):
// at once while restarts are few, then after a pause that doubles up to a cap; never given up.
// A DDS process may be killed again and again by what the plant network sends (a flood): each
// start costs seconds of CPU at a full line, and a supervisor that gives up leaves the line with
// no stop path from any HMI. Debian 12's systemd (252) restarts a unit after a fixed RestartSec
// and, with a start limit, gives up for good (RestartSteps=/RestartMaxDelaySec= came with 254), so
// the pacing is the DDS side's own: the supervisor's under --part both (DdsSupervisor), the DDS
// process's own under its unit, from a record of its starts kept across its restarts (pace_start).

#include <chrono>
#include <cstddef>
#include <deque>
#include <string>

namespace lb::app {

struct RestartPacing {
  // Starts taken at once within `window`: 1 + 20 restarts, the 20 restarts a minute systemd
  // allowed the DDS unit before (StartLimitBurst=20), without the giving up.
  std::size_t free_starts = 21;
  std::chrono::seconds window{60};
  std::chrono::milliseconds first_pause{1000};
  std::chrono::milliseconds longest_pause{30000};
  // A DDS process that ran this long ends the back-off: what ended it was not the loop.
  std::chrono::seconds settled{60};
};

class RestartPacer {
 public:
  using Clock = std::chrono::steady_clock;
  explicit RestartPacer(RestartPacing pacing = {}) : pacing_(pacing) {}

  // The pause before the next start, asked once per start at `now` (the previous one ended).
  std::chrono::milliseconds next_pause(Clock::time_point now);
  // A DDS process starts at `now` (after its pause).
  void started(Clock::time_point now);
  // Starts within the window before `now`.
  std::size_t starts_within(Clock::time_point now) const;
  // Pauses in a row so far (0: none).
  unsigned step() const { return step_; }
  const RestartPacing& pacing() const { return pacing_; }

  // The record kept between processes (text: "step N", then "start NS" per start, NS on the
  // steady clock), and the pacer it describes (lines it does not know are skipped).
  std::string record() const;
  static RestartPacer from_record(const std::string& text, RestartPacing pacing = {});

 private:
  void forget_before(Clock::time_point t);

  RestartPacing pacing_;
  std::deque<Clock::time_point> starts_;
  unsigned step_ = 0;
};

// The DDS process under its unit, first thing: waits as the record at `path` says (stop signals
// end the wait: false, the caller exits), then records this start. A record that cannot be read
// or written costs the pacing, not the start (logged).
bool pace_start(const std::string& path);

}  // namespace lb::app
