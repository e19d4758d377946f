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
//     keeps what it had); one the bridge pauses to write PDO parameters and starts again is. An
//     operator's NMT start of a device the operator's NMT stop took out of operational (both
//     accepted, each frame sent between its request and the answer, or the device's stopped
//     heartbeat within 100 ms after the stop's writing: it answers the stop) is no start either: it
//     resumes the set values in force, as docs/canopen-master.md says of a device held stopped
//     ("that start resumes the set values in force, as after an operator's stop"); a boot-up in
//     between makes it one again.
//     "After that start": after the moment the device left operational (or booted up) before it.
// I2  Every stop the operator sends (the enabling level off, the profile's stopping command, NMT
//     stop) is answered; accepted, its frame is on the bus within 100 ms of the moment the request
//     was written, and before its answer (accepted only once on the bus); refused, with a reason,
//     and only while the device is not heard: a device that is heard gets its stop (design rule
//     4). Heard, as the bridge's bus process can know it: a frame of the device's own (CiA 301
//     heartbeat, EMCY, SDO answer or TPDO) within its heartbeat timeout, sent while that process
//     ran (a frame from before it started never reached it), at every moment from the request's
//     writing until 100 ms later or its answer, if sooner. A stop the bridge can send is on the
//     bus within those 100 ms, so it decides within them; a device that fell silent meanwhile may
//     rightly be refused, one heard all along may not (however late the refusal comes: a stop
//     held back until the device is lost is refused while heard). One exception: a device whose
//     own newest heartbeat says stopped (04h) is held by NMT stop, takes no PDO and answers no SDO
//     (CiA 301); a stop refused for it stops nothing that is not stopped already.
//     Around an outage of the bridge the harness made (its bus process or DDS process killed or
//     stopped, until the harness's own request is answered again): a stop left unanswered is no
//     violation when the outage began before, or within 2 s after, its writing (in flight when a
//     process died, or written while none could take it); one in flight across an outage and
//     answered by the bridge that came back is held to what the operator can expect of a bridge
//     that was not there: accepted, its frame on the bus before its answer (the client library
//     asks again until a bridge answers, so 100 ms from its writing would judge the outage, not
//     the bridge); refused, only while the device was not heard from the outage's end on.
// I3  An enabling level an operator switched off (accepted) stays off on the bus from the frame
//     that showed it until an operator switches it on again: a value accepted is never replaced.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "can/can_frame.hpp"
#include "support/safety_device.hpp"
#include "support/safety_request.hpp"

namespace lb::test::safety {

inline constexpr std::int64_t kStopWithinNs = 100'000'000;
// How much earlier than the NMT command it answers a device's heartbeat may be stamped for the
// report to name the command (two senders' stamps, within the same millisecond as a rule).
inline constexpr std::int64_t kAnswerStampSkewNs = 2'000'000;
// An unanswered request is put down to an outage of the bridge when one began or lasted within this
// time of the request's writing (a request in flight when a process is killed is lost with it).
inline constexpr std::int64_t kOutageReachNs = 2'000'000'000;

struct Violation {
  std::string invariant;  // I1, I2, I3
  std::string text;
  std::int64_t at_ns = 0;  // the moment it concerns: the request's writing, the first frame that broke it
  std::string kind;        // its kind, to count violations by (e.g. "refused while heard")
};

// One run of the bridge's bus process, as the harness started and ended it (realtime, the clock
// the bus stamps frames with): it hears only the frames sent while it runs.
struct BusProcessRun {
  std::int64_t started_ns = 0;
  std::int64_t ended_ns = 0;  // 0: still running
  bool covers(std::int64_t ns) const { return started_ns <= ns && (ended_ns == 0 || ns < ended_ns); }
};

// A span in which the bridge could answer no request, as the harness made it: from the moment it
// killed or stopped a process of the bridge until its own request was answered again (realtime).
struct Outage {
  std::int64_t from_ns = 0;
  std::int64_t back_ns = 0;  // 0: not back yet
  std::string what;
  bool overlaps(std::int64_t from, std::int64_t to) const { return from_ns <= to && (back_ns == 0 || back_ns >= from); }
};

// What the judge knows of the bridge's processes. Nothing: one bus process all along, always
// answering (a table row without a restart, a timeline written by hand).
struct BridgeTimeline {
  std::vector<BusProcessRun> runs;
  std::vector<Outage> outages;
};

// What became of one stop, as I2 reads it.
struct StopOutcome {
  struct Shown {
    const FrameProof* proof = nullptr;
    const lb::can::CanFrame* frame = nullptr;  // the first frame at or after the request that shows it
  };
  std::vector<Shown> shown;                  // accepted: each frame that shows it
  const lb::can::CanFrame* heard = nullptr;  // refused: the device's newest frame, if heard throughout
  // Refused while heard: its own newest heartbeat, when that says stopped (04h): NMT stop is in
  // force, the device takes no PDO and answers no SDO (CiA 301), nothing more can reach or stop it.
  const lb::can::CanFrame* nmt_stopped = nullptr;
  // An outage of the bridge the request met: unanswered, the one that explains it; answered, the
  // one it was in flight across (then judged as I2 says).
  const Outage* outage = nullptr;
  // Accepted: from the request's writing to the last of its frames on the bus (-1: one never was).
  std::int64_t latency_ns(std::int64_t written_ns) const {
    std::int64_t worst = 0;
    for (const auto& s : shown) {
      if (s.frame == nullptr) return -1;
      worst = std::max(worst, s.frame->timestamp_ns - written_ns);
    }
    return worst;
  }
};

// The frames in the order of their stamps (a sender stamps a frame as it sends it, so frames of
// different senders may reach the recorder a few microseconds out of that order): the judge wants it.
inline std::vector<lb::can::CanFrame> by_stamp(std::vector<lb::can::CanFrame> frames) {
  std::stable_sort(frames.begin(), frames.end(),
                   [](const auto& a, const auto& b) { return a.timestamp_ns < b.timestamp_ns; });
  return frames;
}

class SafetyJudge {
 public:
  using Frames = std::vector<lb::can::CanFrame>;

  SafetyJudge(const SafetyDevice& device, int heartbeat_timeout_ms, std::int64_t t0_ns, BridgeTimeline bridge = {})
      : d_(device),
        heartbeat_timeout_ns_(std::int64_t{heartbeat_timeout_ms} * 1'000'000),
        t0_(t0_ns),
        bridge_(std::move(bridge)) {}

  // frames: in the order of their stamps (by_stamp); requests: in the order they were written.
  std::vector<Violation> judge(const Frames& frames, const std::vector<OperatorRequest>& requests) const {
    std::vector<Violation> out;
    const auto on = enabling_times(requests);
    starts(frames, requests, on, out);
    stops(frames, requests, out);
    kept_off(frames, requests, on, out);
    return out;
  }

  StopOutcome outcome(const Frames& frames, const OperatorRequest& r) const {
    StopOutcome o;
    const auto until = r.answered_ns == 0 ? r.written_ns + kOutageReachNs : r.answered_ns;
    for (const auto& g : bridge_.outages) {
      if (g.overlaps(r.written_ns, until)) o.outage = &g;
    }
    if (r.answered_ns == 0) return o;
    if (r.accepted) {
      for (const auto& p : r.proofs) o.shown.push_back({&p, first(frames, r.written_ns, p.match)});
      return o;
    }
    // When the bridge decided: within the stop's 100 ms (or until its answer), or, across an
    // outage, from the outage's end to the answer.
    std::int64_t from = r.written_ns, to = std::min(r.answered_ns, r.written_ns + kStopWithinNs);
    if (o.outage != nullptr) {
      if (o.outage->back_ns == 0 || o.outage->back_ns >= r.answered_ns) return o;
      from = std::max(r.written_ns, o.outage->back_ns);
      to = r.answered_ns;
    }
    o.heard = heard(frames, from, to);
    if (o.heard != nullptr) {
      // Its own newest heartbeat by the end of that time says what state it was in.
      const lb::can::CanFrame* beat = nullptr;
      for (auto it = from_stamp(frames, from - heartbeat_timeout_ns_); it != frames.end() && it->timestamp_ns <= to;
           ++it) {
        if (it->id == d_.heartbeat_id() && it->len >= 1) beat = &*it;
      }
      if (beat != nullptr && (beat->data[0] & 0x7F) == 0x04) o.nmt_stopped = beat;
    }
    return o;
  }

  // Every stop with what became of it: its answer and, accepted, how long after its request each
  // frame that shows it was on the bus (for the log of a row, pass or fail).
  std::string stop_times(const Frames& frames, const std::vector<OperatorRequest>& requests) const {
    std::string out;
    for (const auto& r : requests) {
      if (!r.stops()) continue;
      out += "  " + request(r);
      for (const auto& s : outcome(frames, r).shown) {
        out += s.frame == nullptr
                   ? "; never on the bus"
                   : fmt::format("; on the bus after {:.1f} ms", (s.frame->timestamp_ns - r.written_ns) / 1e6);
      }
      out += "\n";
    }
    return out;
  }

  // The device heard by the bus process at every moment of [from, to]: the newest frame of its
  // own at or before `from`, sent while the process that runs at `from` ran, within its heartbeat
  // timeout, and no silence longer than that timeout until `to`. Returns that newest frame, or
  // nullptr when the device was not heard throughout (or no bus process ran).
  const lb::can::CanFrame* heard(const Frames& frames, std::int64_t from, std::int64_t to) const {
    std::int64_t since = from - heartbeat_timeout_ns_;
    if (!bridge_.runs.empty()) {
      const auto run = std::find_if(bridge_.runs.begin(), bridge_.runs.end(),
                                    [&](const auto& r) { return r.covers(from); });
      if (run == bridge_.runs.end() || !run->covers(to)) return nullptr;
      since = std::max(since, run->started_ns);
    }
    const lb::can::CanFrame* before = nullptr;
    std::int64_t last = 0;
    for (auto it = from_stamp(frames, since); it != frames.end() && it->timestamp_ns <= to; ++it) {
      if (!d_.own(*it)) continue;
      if (it->timestamp_ns <= from) {
        before = &*it;
      } else if (before == nullptr || it->timestamp_ns - last > heartbeat_timeout_ns_) {
        return nullptr;  // silent for longer than its timeout after the request was written
      }
      last = it->timestamp_ns;
    }
    if (before == nullptr || to - last > heartbeat_timeout_ns_) return nullptr;
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
  static Frames::const_iterator from_stamp(const Frames& frames, std::int64_t from) {
    return std::partition_point(frames.begin(), frames.end(),
                                [from](const lb::can::CanFrame& f) { return f.timestamp_ns < from; });
  }
  // The first frame stamped at or after `from` that matches.
  static const lb::can::CanFrame* first(const Frames& frames, std::int64_t from, const FrameMatch& match) {
    for (auto it = from_stamp(frames, from); it != frames.end(); ++it) {
      if (match(*it)) return &*it;
    }
    return nullptr;
  }
  bool nmt_to_device(const lb::can::CanFrame& f) const {
    return f.id == 0 && f.len == 2 && (f.data[1] == d_.node || f.data[1] == 0);
  }
  // When the operator's accepted enabling set values were written, in order.
  static std::vector<std::int64_t> enabling_times(const std::vector<OperatorRequest>& requests) {
    std::vector<std::int64_t> on;
    for (const auto& r : requests) {
      if (r.kind == OperatorRequest::Kind::enabling_on && r.accepted) on.push_back(r.written_ns);
    }
    std::sort(on.begin(), on.end());
    return on;
  }
  // An accepted enabling set value written in [from, before).
  static bool enabling_set(const std::vector<std::int64_t>& on, std::int64_t from, std::int64_t before) {
    const auto it = std::lower_bound(on.begin(), on.end(), from);
    return it != on.end() && *it < before;
  }

  // What a frame that took the device out of operational is, for a violation's kind.
  std::string left_by(const lb::can::CanFrame& f) const {
    if (f.id == 0) {
      switch (f.data[0]) {
        case 0x02: return "NMT stop";
        case 0x80: return "NMT enter pre-operational";
        case 0x81: return "NMT reset node";
        case 0x82: return "NMT reset communication";
        default: return "NMT command";
      }
    }
    if ((f.data[0] & 0x7F) == 0x04) return "its stopped heartbeat";
    if ((f.data[0] & 0x7F) == 0x7F) return "its pre-operational heartbeat";
    return "its boot-up";
  }

  // The device's stopped heartbeat `hb` answers an operator's accepted NMT stop written at most
  // 100 ms before it: the device stops within microseconds of the command, and the command's own
  // frame may carry a stamp after the answer's (two senders' stamps; under load, the campaign saw
  // the heartbeat first by over 2 ms: corrugator +1208.833 s, feeders +1568.265 s).
  static bool stop_answered(const std::vector<OperatorRequest>& requests, const lb::can::CanFrame& hb) {
    return std::any_of(requests.begin(), requests.end(), [&](const OperatorRequest& r) {
      return r.kind == OperatorRequest::Kind::nmt_stop && r.accepted && r.written_ns <= hb.timestamp_ns &&
             hb.timestamp_ns - r.written_ns <= kStopWithinNs;
    });
  }
  // An accepted operator's request of this kind whose frame `f` is (sent between its writing and
  // its answer).
  static bool requested(const std::vector<OperatorRequest>& requests, OperatorRequest::Kind kind,
                        const lb::can::CanFrame& f) {
    return std::any_of(requests.begin(), requests.end(), [&](const OperatorRequest& r) {
      return r.kind == kind && r.accepted && r.written_ns <= f.timestamp_ns && f.timestamp_ns <= r.answered_ns;
    });
  }
  // The operator's requests written within 200 ms of `f`, with their answers: what a reader of a
  // violation needs to tell a device's own act from the answer to a request.
  std::string requests_near(const std::vector<OperatorRequest>& requests, const lb::can::CanFrame& f) const {
    constexpr std::int64_t kNearNs = 200'000'000;
    std::string out;
    for (const auto& r : requests) {
      if (r.written_ns >= f.timestamp_ns - kNearNs && r.written_ns <= f.timestamp_ns + kNearNs) {
        out += "; near it: " + request(r);
      }
    }
    return out.empty() ? "; no operator's request written within 200 ms of it" : out;
  }

  void starts(const Frames& frames, const std::vector<OperatorRequest>& requests, const std::vector<std::int64_t>& on,
              std::vector<Violation>& out) const {
    enum class State { unknown, pre_operational, operational, stopped };
    State state = State::unknown;
    const lb::can::CanFrame* left = nullptr;  // its boot-up or the frame that took it out of operational
    struct Start {
      std::int64_t from;  // operator set values from here on count
      std::string how;
      std::string kind;
      std::size_t enabled = 0;  // enabling RPDOs after it without an operator's set value
      const lb::can::CanFrame* first = nullptr;
      const lb::can::CanFrame* left = nullptr;  // what took the device out of operational before it
    };
    std::vector<Start> starts;
    // What took it out of operational was the operator's NMT stop: its frame, or the device's
    // stopped heartbeat that answers it (see stop_answered).
    bool left_by_operator = false;
    const auto leave = [&](const lb::can::CanFrame& f, State to, bool by_operator) {
      if (state == State::operational || state == State::unknown) {
        left = &f;
        left_by_operator = by_operator;
      }
      state = to;
    };
    // The device's heartbeat that answers an NMT command may carry a stamp a little before the
    // command's (two senders stamp their own frames, and the device answers within microseconds):
    // such a heartbeat left operational because of that command, which the report then names.
    // Whether that was the operator's stop is stop_answered's to say.
    const auto caused = [&](const lb::can::CanFrame& command, std::uint8_t answer) {
      if (left == nullptr || left->id != d_.heartbeat_id() || (left->data[0] & 0x7F) != answer) return;
      if (command.timestamp_ns - left->timestamp_ns <= kAnswerStampSkewNs) left = &command;
    };
    for (const auto& f : frames) {
      if (f.id == d_.heartbeat_id() && f.len >= 1) {
        const auto s = f.data[0] & 0x7F;
        if (s == 0x00) {
          state = State::pre_operational;
          left = &f;
          left_by_operator = false;
          starts.push_back({f.timestamp_ns, "its boot-up " + frame(f), "after a boot-up"});
        } else if (s == 0x05) {
          state = State::operational;  // it says so (its start, if any, was seen as the NMT start)
        } else if (s == 0x7F && state == State::operational) {
          leave(f, State::pre_operational, false);
        } else if (s == 0x04 && state == State::operational) {
          leave(f, State::stopped, stop_answered(requests, f));
        }
      } else if (nmt_to_device(f)) {
        switch (f.data[0]) {
          case 0x01:
            if (state != State::operational) {
              if (left != nullptr && left_by_operator && requested(requests, OperatorRequest::Kind::nmt_start, f)) {
                // The operator's start after the operator's stop: the set values in force resume.
              } else if (left == nullptr) {
                starts.push_back({0, "NMT start " + frame(f), "after an NMT start"});
              } else {
                starts.push_back({left->timestamp_ns,
                                  fmt::format("NMT start {} (it had left operational by {} {})", frame(f),
                                              left_by(*left), frame(*left)),
                                  "after an NMT start, out of operational by " + left_by(*left), 0, nullptr, left});
              }
              state = State::operational;
            }
            break;
          case 0x02:
            caused(f, 0x04);
            leave(f, State::stopped, requested(requests, OperatorRequest::Kind::nmt_stop, f));
            break;
          case 0x80:
            caused(f, 0x7F);
            leave(f, State::pre_operational, false);
            break;
          case 0x81:
          case 0x82: leave(f, State::pre_operational, false); break;
          default: break;
        }
      } else if (d_.enabled(f) && !starts.empty()) {
        auto& s = starts.back();
        if (!enabling_set(on, s.from, f.timestamp_ns) && s.enabled++ == 0) s.first = &f;
      }
    }
    for (const auto& s : starts) {
      if (s.enabled == 0) continue;
      out.push_back({"I1",
                     fmt::format("after {} ({} start counted from {}), {} RPDO(s) carried an enabling level "
                                 "with no operator's enabling set value accepted since; the first: {}",
                                 s.how, d_.name, at(s.from), s.enabled, frame(*s.first)) +
                         (s.left == nullptr ? "" : requests_near(requests, *s.left)),
                     s.first->timestamp_ns, s.kind});
    }
  }

  void stops(const Frames& frames, const std::vector<OperatorRequest>& requests, std::vector<Violation>& out) const {
    for (const auto& r : requests) {
      if (!r.stops()) continue;
      const auto o = outcome(frames, r);
      const auto add = [&](std::string text, const char* kind) {
        out.push_back({"I2", std::move(text), r.written_ns, kind});
      };
      if (r.answered_ns == 0) {
        if (o.outage == nullptr) add("a stop was never answered: " + request(r), "never answered");
        continue;
      }
      if (!r.accepted) {
        if (r.reason.empty()) add("a stop refused without a reason: " + request(r), "refused without a reason");
        if (o.heard == nullptr || o.nmt_stopped != nullptr) continue;
        if (o.outage == nullptr) {
          add(fmt::format("a stop refused while the device is heard (its frame {}, {:.0f} ms before, and heard "
                          "for 100 ms after; heartbeat timeout {} ms): {}",
                          frame(*o.heard), (r.written_ns - o.heard->timestamp_ns) / 1e6,
                          heartbeat_timeout_ns_ / 1'000'000, request(r)),
              "refused while heard");
        } else {
          add(fmt::format("a stop refused while the device is heard from the end of {} ({}) to the answer (its "
                          "frame {}; heartbeat timeout {} ms): {}",
                          o.outage->what, at(o.outage->back_ns), frame(*o.heard), heartbeat_timeout_ns_ / 1'000'000,
                          request(r)),
              "refused while heard after an outage");
        }
        continue;
      }
      for (const auto& s : o.shown) {
        if (s.frame == nullptr) {
          add(fmt::format("a stop accepted and never on the bus (no {}; frames recorded until {}): {}", s.proof->what,
                          frames.empty() ? "-" : at(frames.back().timestamp_ns), request(r)),
              "accepted, never on the bus");
        } else if (s.frame->timestamp_ns > r.answered_ns) {
          add(fmt::format("a stop answered accepted before it was on the bus ({} came {:.1f} ms after the "
                          "answer{}): {}",
                          frame(*s.frame), (s.frame->timestamp_ns - r.answered_ns) / 1e6,
                          o.outage == nullptr ? "" : "; in flight across " + o.outage->what, request(r)),
              "answered accepted before on the bus");
        } else if (o.outage == nullptr && s.frame->timestamp_ns - r.written_ns > kStopWithinNs) {
          add(fmt::format("a stop accepted and on the bus only {:.1f} ms after its request (over 100 ms): {} for {}",
                          (s.frame->timestamp_ns - r.written_ns) / 1e6, frame(*s.frame), request(r)),
              "accepted, on the bus after over 100 ms");
        }
      }
    }
  }

  void kept_off(const Frames& frames, const std::vector<OperatorRequest>& requests, const std::vector<std::int64_t>& on,
                std::vector<Violation>& out) const {
    for (const auto& r : requests) {
      if (r.kind != OperatorRequest::Kind::enabling_off || !r.accepted) continue;
      // An operator's enabling set value after this one lets the level on again from then on.
      const auto next_on = std::upper_bound(on.begin(), on.end(), r.written_ns);
      const std::int64_t until = next_on == on.end() ? std::numeric_limits<std::int64_t>::max() : *next_on;
      for (const auto& e : d_.enabling) {
        const lb::can::CanFrame* off = nullptr;
        const lb::can::CanFrame* again = nullptr;
        std::size_t on_again = 0;
        for (auto it = from_stamp(frames, r.written_ns); it != frames.end() && it->timestamp_ns < until; ++it) {
          if (it->id != e.cob_id) continue;
          if (off == nullptr) {
            if (!e.enabled(*it)) off = &*it;
            continue;
          }
          if (e.enabled(*it) && on_again++ == 0) again = &*it;
        }
        if (on_again != 0) {
          out.push_back({"I3",
                         fmt::format("{} showed the level off at {}, then {} RPDO(s) carried it on again with no "
                                     "operator's enabling set value since; the first: {} ({})",
                                     request(r), frame(*off), on_again, frame(*again), e.what),
                         again->timestamp_ns, "switched on again"});
        }
      }
    }
  }

  const SafetyDevice& d_;
  std::int64_t heartbeat_timeout_ns_;
  std::int64_t t0_;
  BridgeTimeline bridge_;
};

}  // namespace lb::test::safety
