#pragma once
// The safety table's judge: the invariants of issue 40, decided from the recorded frames (bus
// stamps, realtime) and the operator's requests with their answers, nothing else.
//
// I1  No RPDO with an enabling bit or field non-zero after a start of the device until an operator
//     set an enabling value (accepted) after that start. A start: the device's own boot-up
//     (70Xh#00), or an NMT start (000#01XX, 000#0100) to a device that was not operational. What
//     the device was is followed from the frames alone: a boot-up makes it pre-operational, NMT
//     stop / enter pre-operational / reset take it out of operational, NMT start into it, its own
//     heartbeat says what it is. A device the restarted bridge finds running is not started (it
//     keeps what it had); one the bridge pauses to write PDO parameters and starts again is.
//     "After that start": after the moment the device left operational (or booted up) before it.
// I2  Every stop the operator sends (the enabling level off, the profile's stopping command, NMT
//     stop) is answered; accepted, its frame is on the bus within 100 ms of the moment the request
//     was written; refused, with a reason, and only while the device is not heard: a device that
//     is heard gets its stop (design rule 4). Heard, as the bridge's bus process can know it: a
//     frame of the device's own (CiA 301 heartbeat, EMCY, SDO answer or TPDO) within its heartbeat
//     timeout, sent while that process ran (a frame from before it started never reached it), at
//     every moment from the request's writing until 100 ms later or its answer, if sooner. A stop
//     the bridge can send is on the bus within those 100 ms, so it decides within them; a device
//     that fell silent meanwhile may rightly be refused, one heard all along may not (however late
//     the refusal comes: a stop held back until the device is lost is refused while heard).
// I3  An enabling level an operator switched off (accepted) stays off on the bus from the frame
//     that showed it until an operator switches it on again: a value accepted is never replaced.

#include <algorithm>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "can/can_frame.hpp"
#include "support/safety_device.hpp"
#include "support/safety_request.hpp"

namespace lb::test::safety {

inline constexpr std::int64_t kStopWithinNs = 100'000'000;

struct Violation {
  std::string invariant;  // I1, I2, I3
  std::string text;
};

// One run of the bridge's bus process, as the harness started and ended it (realtime, the clock
// the bus stamps frames with): it hears only the frames sent while it runs.
struct BusProcessRun {
  std::int64_t started_ns = 0;
  std::int64_t ended_ns = 0;  // 0: still running
  bool covers(std::int64_t ns) const { return started_ns <= ns && (ended_ns == 0 || ns < ended_ns); }
};

class SafetyJudge {
 public:
  // `runs`: the bus process's runs; none given, one that ran all along (a timeline written by hand).
  SafetyJudge(const SafetyDevice& device, int heartbeat_timeout_ms, std::int64_t t0_ns,
              std::vector<BusProcessRun> runs = {})
      : d_(device),
        heartbeat_timeout_ns_(std::int64_t{heartbeat_timeout_ms} * 1'000'000),
        t0_(t0_ns),
        runs_(std::move(runs)) {}

  std::vector<Violation> judge(const std::vector<lb::can::CanFrame>& frames,
                               const std::vector<OperatorRequest>& requests) const {
    std::vector<Violation> out;
    starts(frames, requests, out);
    stops(frames, requests, out);
    kept_off(frames, requests, out);
    return out;
  }

  // Every stop with what became of it: its answer and, accepted, how long after its request each
  // frame that shows it was on the bus (for the log of a row, pass or fail).
  std::string stop_times(const std::vector<lb::can::CanFrame>& frames,
                         const std::vector<OperatorRequest>& requests) const {
    std::string out;
    for (const auto& r : requests) {
      if (!r.stops()) continue;
      out += "  " + request(r);
      if (r.accepted) {
        for (const auto& p : r.proofs) {
          const auto* f = first(frames, r.written_ns, p.match);
          out += f == nullptr ? "; never on the bus"
                              : fmt::format("; on the bus after {:.1f} ms", (f->timestamp_ns - r.written_ns) / 1e6);
        }
      }
      out += "\n";
    }
    return out;
  }

  // The device heard by the bus process at every moment of [from, to]: the newest frame of its
  // own at or before `from`, sent while the process that runs at `from` ran, within its heartbeat
  // timeout, and no silence longer than that timeout until `to`. Returns that newest frame, or
  // nullptr when the device was not heard throughout (or no bus process ran).
  const lb::can::CanFrame* heard(const std::vector<lb::can::CanFrame>& frames, std::int64_t from,
                                 std::int64_t to) const {
    std::int64_t since = 0;
    if (!runs_.empty()) {
      const auto run = std::find_if(runs_.begin(), runs_.end(), [&](const auto& r) { return r.covers(from); });
      if (run == runs_.end() || !run->covers(to)) return nullptr;
      since = run->started_ns;
    }
    const lb::can::CanFrame* before = nullptr;
    std::int64_t last = 0;
    for (const auto& f : frames) {
      if (f.timestamp_ns > to) break;
      if (f.timestamp_ns < since || !d_.own(f)) continue;
      if (f.timestamp_ns <= from) {
        before = &f;
      } else if (before == nullptr || f.timestamp_ns - last > heartbeat_timeout_ns_) {
        return nullptr;  // silent for longer than its timeout after the request was written
      }
      last = f.timestamp_ns;
    }
    if (before == nullptr || from - before->timestamp_ns > heartbeat_timeout_ns_ || to - last > heartbeat_timeout_ns_)
      return nullptr;
    return before;
  }

  std::string at(std::int64_t ns) const { return fmt::format("+{:.3f} s", static_cast<double>(ns - t0_) / 1e9); }
  std::string frame(const lb::can::CanFrame& f) const {
    std::string s = fmt::format("{} {:03X}#", at(f.timestamp_ns), f.id);
    for (unsigned i = 0; i < f.len; ++i) s += fmt::format("{:02X}", f.data[i]);
    return s;
  }
  std::string request(const OperatorRequest& r) const {
    return fmt::format("'{}' written {}, {}", r.what, at(r.written_ns),
                       r.answered_ns == 0 ? "never answered (" + r.reason + ")"
                                          : (r.accepted ? "accepted" : "refused: '" + r.reason + "'") +
                                                fmt::format(" {}", at(r.answered_ns)));
  }

 private:
  // The first frame stamped at or after `from` that matches.
  static const lb::can::CanFrame* first(const std::vector<lb::can::CanFrame>& frames, std::int64_t from,
                                        const FrameMatch& match) {
    for (const auto& f : frames) {
      if (f.timestamp_ns >= from && match(f)) return &f;
    }
    return nullptr;
  }
  bool nmt_to_device(const lb::can::CanFrame& f) const {
    return f.id == 0 && f.len == 2 && (f.data[1] == d_.node || f.data[1] == 0);
  }
  // An accepted enabling set value written in [from, before).
  const OperatorRequest* enabling_set(const std::vector<OperatorRequest>& requests, std::int64_t from,
                                      std::int64_t before) const {
    for (const auto& r : requests) {
      if (r.kind == OperatorRequest::Kind::enabling_on && r.accepted && r.written_ns >= from && r.written_ns < before)
        return &r;
    }
    return nullptr;
  }

  void starts(const std::vector<lb::can::CanFrame>& frames, const std::vector<OperatorRequest>& requests,
              std::vector<Violation>& out) const {
    enum class State { unknown, pre_operational, operational, stopped };
    State state = State::unknown;
    std::int64_t left_operational = 0;  // boot-up or the moment it left operational
    struct Start {
      std::int64_t from;  // operator set values from here on count
      std::string how;
      std::size_t enabled = 0;  // enabling RPDOs after it without an operator's set value
      std::string first;
    };
    std::vector<Start> starts;
    const auto leave = [&](const lb::can::CanFrame& f, State to) {
      if (state == State::operational || state == State::unknown) left_operational = f.timestamp_ns;
      state = to;
    };
    for (const auto& f : frames) {
      if (f.id == d_.heartbeat_id() && f.len >= 1) {
        const auto s = f.data[0] & 0x7F;
        if (s == 0x00) {
          state = State::pre_operational;
          left_operational = f.timestamp_ns;
          starts.push_back({f.timestamp_ns, "its boot-up " + frame(f), 0, {}});
        } else if (s == 0x05) {
          state = State::operational;  // it says so (its start, if any, was seen as the NMT start)
        } else if (s == 0x7F && state == State::operational) {
          leave(f, State::pre_operational);
        } else if (s == 0x04 && state == State::operational) {
          leave(f, State::stopped);
        }
      } else if (nmt_to_device(f)) {
        switch (f.data[0]) {
          case 0x01:
            if (state != State::operational) {
              starts.push_back({left_operational, "NMT start " + frame(f), 0, {}});
              state = State::operational;
            }
            break;
          case 0x02: leave(f, State::stopped); break;
          case 0x80: leave(f, State::pre_operational); break;
          case 0x81:
          case 0x82: leave(f, State::pre_operational); break;
          default: break;
        }
      } else if (d_.enabled(f) && !starts.empty()) {
        auto& s = starts.back();
        if (enabling_set(requests, s.from, f.timestamp_ns) == nullptr) {
          if (s.enabled++ == 0) s.first = frame(f);
        }
      }
    }
    for (const auto& s : starts) {
      if (s.enabled == 0) continue;
      out.push_back({"I1", fmt::format("after {} ({} start counted from {}), {} RPDO(s) carried an enabling level "
                                       "with no operator's enabling set value accepted since; the first: {}",
                                       s.how, d_.name, at(s.from), s.enabled, s.first)});
    }
  }

  void stops(const std::vector<lb::can::CanFrame>& frames, const std::vector<OperatorRequest>& requests,
             std::vector<Violation>& out) const {
    for (const auto& r : requests) {
      if (!r.stops()) continue;
      if (r.answered_ns == 0) {
        out.push_back({"I2", "a stop was never answered: " + request(r)});
        continue;
      }
      if (!r.accepted) {
        if (r.reason.empty()) out.push_back({"I2", "a stop refused without a reason: " + request(r)});
        if (const auto* last_own = heard(frames, r.written_ns, std::min(r.answered_ns, r.written_ns + kStopWithinNs))) {
          out.push_back({"I2", fmt::format("a stop refused while the device is heard (its frame {}, {:.0f} ms "
                                           "before, and heard for 100 ms after; heartbeat timeout {} ms): {}",
                                           frame(*last_own), (r.written_ns - last_own->timestamp_ns) / 1e6,
                                           heartbeat_timeout_ns_ / 1'000'000, request(r))});
        }
        continue;
      }
      for (const auto& p : r.proofs) {
        const auto* shown = first(frames, r.written_ns, p.match);
        if (shown == nullptr) {
          out.push_back({"I2", fmt::format("a stop accepted and never on the bus (no {}; frames recorded until {}): {}",
                                           p.what, frames.empty() ? "-" : at(frames.back().timestamp_ns), request(r))});
        } else if (shown->timestamp_ns - r.written_ns > kStopWithinNs) {
          out.push_back({"I2", fmt::format("a stop accepted and on the bus only {:.1f} ms after its request (over "
                                           "100 ms): {} for {}",
                                           (shown->timestamp_ns - r.written_ns) / 1e6, frame(*shown), request(r))});
        }
      }
    }
  }

  void kept_off(const std::vector<lb::can::CanFrame>& frames, const std::vector<OperatorRequest>& requests,
                std::vector<Violation>& out) const {
    for (const auto& r : requests) {
      if (r.kind != OperatorRequest::Kind::enabling_off || !r.accepted) continue;
      for (const auto& e : d_.enabling) {
        const lb::can::CanFrame* off = nullptr;
        std::size_t on_again = 0;
        std::string first;
        for (const auto& f : frames) {
          if (f.id != e.cob_id || f.timestamp_ns < r.written_ns) continue;
          if (off == nullptr) {
            if (!e.enabled(f)) off = &f;
            continue;
          }
          if (e.enabled(f) && enabling_set(requests, r.written_ns + 1, f.timestamp_ns) == nullptr) {
            if (on_again++ == 0) first = frame(f);
          }
        }
        if (on_again != 0) {
          out.push_back({"I3", fmt::format("{} showed the level off at {}, then {} RPDO(s) carried it on again with no "
                                           "operator's enabling set value since; the first: {} ({})",
                                           request(r), frame(*off), on_again, first, e.what)});
        }
      }
    }
  }

  const SafetyDevice& d_;
  std::int64_t heartbeat_timeout_ns_;
  std::int64_t t0_;
  std::vector<BusProcessRun> runs_;
};

}  // namespace lb::test::safety
