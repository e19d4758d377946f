#pragma once
// What the fault campaign prints: the faults injected by kind, the operators' stops and what became
// of them, the time from a stop's request to its frame on the bus (p50/p99/max), and every
// violation with its frames (the device's own and the bridge's to it around the moment, the
// faults and the spoofed frames near it), so that a violation can be read without the logs and
// replayed from the seed.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "campaign/campaign_judge.hpp"
#include "campaign/campaign_line.hpp"
#include "campaign/fault_schedule.hpp"
#include "support/safety_judge.hpp"

namespace lb::test::campaign {

// A fault's step as the campaign carried it out.
struct Executed {
  std::int64_t ns = 0;  // realtime, when it was done
  std::size_t fault = 0;
  int step = 0;
  bool done = true;  // false: it could not be (no DDS process to kill: the bridge was down)
};

// The first frame stamped at or after `ns` (frames in the order of their stamps).
inline std::vector<lb::can::CanFrame>::const_iterator from_stamp(const std::vector<lb::can::CanFrame>& frames,
                                                                 std::int64_t ns) {
  return std::partition_point(frames.begin(), frames.end(),
                              [ns](const lb::can::CanFrame& f) { return f.timestamp_ns < ns; });
}

struct StopFigures {
  struct Kind {
    std::size_t sent = 0, on_bus = 0, across_outage = 0, refused_not_heard = 0, refused_nmt_stopped = 0,
                unanswered_in_outage = 0, judged_violation = 0;
  };
  std::map<std::string, Kind> by_kind;           // enabling level off, stopping command, NMT stop
  std::vector<std::int64_t> latency_ns;          // accepted, not across an outage: request to its last frame
  std::vector<std::int64_t> changed_latency_ns;  // of those, the ones whose frame changed the bus
  std::vector<std::int64_t> outage_latency_ns;   // accepted across an outage: request to its last frame

  static std::string kind_of(const safety::OperatorRequest& r) {
    switch (r.kind) {
      case safety::OperatorRequest::Kind::enabling_off: return "enabling level off (set value)";
      case safety::OperatorRequest::Kind::stopping: return "stopping command (command / feeder stop_mode)";
      case safety::OperatorRequest::Kind::nmt_stop: return "NMT stop";
      default: return "other";
    }
  }

  static StopFigures of(const CampaignJudge& judge, const Record& record, const std::vector<Found>& violations) {
    StopFigures out;
    for (std::size_t i = 0; i < record.requests.size(); ++i) {
      const auto j = judge.for_device(i, record.bridge);
      const auto& frames = record.frames[i];
      for (const auto& r : record.requests[i]) {
        if (!r.stops()) continue;
        auto& k = out.by_kind[kind_of(r)];
        ++k.sent;
        if (std::any_of(violations.begin(), violations.end(), [&](const Found& f) {
              return f.device == i && f.violation.invariant == "I2" && f.violation.at_ns == r.written_ns;
            })) {
          ++k.judged_violation;
          continue;
        }
        const auto o = j.outcome(frames, r);
        if (r.answered_ns == 0) {
          ++k.unanswered_in_outage;
        } else if (!r.accepted) {
          ++(o.nmt_stopped != nullptr ? k.refused_nmt_stopped : k.refused_not_heard);
        } else if (o.outage != nullptr) {
          ++k.across_outage;
          out.outage_latency_ns.push_back(o.latency_ns(r.written_ns));
        } else {
          ++k.on_bus;
          const auto latency = o.latency_ns(r.written_ns);
          out.latency_ns.push_back(latency);
          if (changed_the_bus(frames, r, o)) out.changed_latency_ns.push_back(latency);
        }
      }
    }
    return out;
  }

  // One of its frames differs from the newest frame of that identifier before the request: the
  // stop changed what the bus said (a level already off shows "off" in the next cyclic RPDO too).
  static bool changed_the_bus(const std::vector<lb::can::CanFrame>& frames, const safety::OperatorRequest& r,
                              const safety::StopOutcome& o) {
    for (const auto& s : o.shown) {
      if (s.frame == nullptr) continue;
      const lb::can::CanFrame* before = nullptr;
      for (auto it = from_stamp(frames, r.written_ns); it != frames.begin();) {
        --it;
        if (it->id == s.frame->id) {
          before = &*it;
          break;
        }
      }
      if (before == nullptr || !s.proof->match(*before) || s.frame->id == 0 || (s.frame->id & 0x780) == 0x600)
        return true;
    }
    return false;
  }
};

inline std::string percentiles(std::vector<std::int64_t> ns) {
  if (ns.empty()) return "none";
  std::sort(ns.begin(), ns.end());
  const auto at = [&](double q) {
    const auto k = static_cast<std::size_t>(std::ceil(q * static_cast<double>(ns.size())));
    return ns[std::min(ns.size() - 1, k == 0 ? 0 : k - 1)] / 1e6;
  };
  return fmt::format("n {}, p50 {:.1f} ms, p99 {:.1f} ms, max {:.1f} ms", ns.size(), at(0.50), at(0.99),
                     ns.back() / 1e6);
}

// How many violations of each kind, per device: "I1 after a boot-up: saw31 2, feeders 1".
inline std::string violations_by_kind(const CampaignLine& line, const std::vector<Found>& violations) {
  std::map<std::string, std::map<std::string, std::size_t>> kinds;
  for (const auto& f : violations) {
    ++kinds[f.violation.invariant + " " + f.violation.kind][line.devices()[f.device].device.name];
  }
  std::string out;
  for (const auto& [kind, devices] : kinds) {
    std::size_t n = 0;
    std::string each;
    for (const auto& [device, count] : devices) {
      n += count;
      each += fmt::format("{}{} {}", each.empty() ? "" : ", ", device, count);
    }
    out += fmt::format("  {:>4}  {} ({})\n", n, kind, each);
  }
  return out;
}

inline std::string fault_text(const FaultSchedule& s, std::size_t i) {
  return fmt::format("{}: {}", name(s.faults[i].kind), s.faults[i].variant);
}

// The frames of device `d` (its own, and the bridge's to it: NMT, RPDOs, SDO requests) in
// [from, to], a run of frames that repeat the one before on the same identifier shown once.
inline std::string device_frames(const safety::SafetyJudge& judge, const SafetyDevice& d,
                                 const std::vector<lb::can::CanFrame>& frames, std::int64_t from, std::int64_t to) {
  const auto n = static_cast<std::uint32_t>(d.node);
  const auto related = [&](const lb::can::CanFrame& f) {
    if (f.id == 0) return f.len == 2 && (f.data[1] == n || f.data[1] == 0);
    return d.own(f) || f.id == 0x200 + n || f.id == 0x300 + n || f.id == 0x400 + n || f.id == 0x500 + n ||
           f.id == 0x600 + n;
  };
  std::string out;
  std::map<std::uint32_t, const lb::can::CanFrame*> last;  // the last frame shown per identifier
  std::map<std::uint32_t, std::size_t> same;
  const auto flush = [&](std::uint32_t id) {
    if (same[id] > 0) out += fmt::format("        ({} more {:03X}h the same)\n", same[id], id);
    same[id] = 0;
  };
  for (auto it = from_stamp(frames, from); it != frames.end() && it->timestamp_ns <= to; ++it) {
    const auto& f = *it;
    if (!related(f)) continue;
    auto& l = last[f.id];
    if (l != nullptr && l->len == f.len && std::equal(f.data.begin(), f.data.begin() + f.len, l->data.begin())) {
      ++same[f.id];
      continue;
    }
    flush(f.id);
    l = &f;
    out += "      " + judge.frame(f) + "\n";
  }
  for (auto& [id, count] : same) {
    if (count > 0) out += fmt::format("        ({} more {:03X}h the same)\n", count, id);
  }
  return out;
}

inline std::string describe(const Found& found, const Record& record, CampaignLine& line, const CampaignJudge& judge,
                            const FaultSchedule& schedule, const std::vector<Executed>& executed,
                            const std::vector<SpoofedFrame>& spoofed) {
  const auto& dev = line.devices()[found.device];
  const auto j = judge.for_device(found.device, record.bridge);
  const auto at = found.violation.at_ns;
  std::string out = fmt::format("  [{}] {} ({}, node {} on {}) at {}: {}\n", found.violation.invariant, dev.device.name,
                                dev.device.column, dev.device.node, dev.bus, j.at(at), found.violation.text);
  // The device's own last fault before the moment, however long ago (a 1017h written stays).
  const auto own_fault = [&](const Fault& f) {
    switch (f.kind) {
      case FaultKind::power_cycle:
      case FaultKind::device_stall:
      case FaultKind::spoofed_heartbeats:
      case FaultKind::spoofed_sdo: return f.target == found.device;
      default: return false;
    }
  };
  for (auto it = executed.rbegin(); it != executed.rend(); ++it) {
    if (it->ns <= at && it->step == 0 && own_fault(schedule.faults[it->fault])) {
      out += fmt::format("    its last fault: {} at {}\n", fault_text(schedule, it->fault), j.at(it->ns));
      break;
    }
  }
  out += "    faults from 10 s before to 2 s after:\n";
  for (const auto& e : executed) {
    if (e.ns < at - 10'000'000'000 || e.ns > at + 2'000'000'000) continue;
    const auto kind = schedule.faults[e.fault].kind;
    const bool spoof = kind == FaultKind::spoofed_heartbeats || kind == FaultKind::spoofed_syncs ||
                       kind == FaultKind::spoofed_sdo;
    if (spoof && e.step != 0) continue;  // its frames are listed below
    out += fmt::format("      {} {} {}{}\n", j.at(e.ns),
                       e.step == 0 ? "begins:" : "ends:  ", fault_text(schedule, e.fault),
                       e.done ? "" : " (not done: no such process)");
  }
  std::string spoofs;
  for (const auto& s : spoofed) {
    if (s.bus != dev.bus || s.frame.timestamp_ns < at - 10'000'000'000 || s.frame.timestamp_ns > at + 1'000'000'000)
      continue;
    spoofs += " " + j.frame(s.frame);
  }
  out += "    spoofed frames on " + dev.bus + " from 10 s before to 1 s after:" + (spoofs.empty() ? " none" : spoofs) +
         "\n";
  for (const auto& o : record.bridge.outages) {
    if (o.from_ns > at + 2'000'000'000 || (o.back_ns != 0 && o.back_ns < at - 10'000'000'000)) continue;
    out += fmt::format("    outage: {} from {} until {}\n", o.what, j.at(o.from_ns),
                       o.back_ns == 0 ? "the end" : j.at(o.back_ns));
  }
  for (const auto& r : record.requests[found.device]) {
    if (r.written_ns < at - 3'000'000'000 || r.written_ns > at + 500'000'000) continue;
    out += "    operator: " + j.request(r) + "\n";
  }
  out += "    " + dev.device.name + "'s frames (its own and the bridge's to it) from 1 s before to 0.3 s after:\n";
  out += device_frames(j, dev.device, record.frames[found.device], at - 1'000'000'000, at + 300'000'000);
  return out;
}

}  // namespace lb::test::campaign
