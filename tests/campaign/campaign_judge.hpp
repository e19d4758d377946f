#pragma once
// The fault campaign's verdicts: the safety table's judge (support/safety_judge.hpp: I1 no enabling
// level after a start until an operator sets one, I2 every stop answered and on the bus within
// 100 ms or refused only while the device is not heard, I3 a level switched off is not switched on
// again by anyone but an operator) over each device's bus frames and its operator's requests, with
// the bridge's runs and outages the harness kept. Run every few seconds on what is recorded up to
// a horizon past which nothing is pending (violations printed as they are found), and once at the
// end over everything: that is the verdict.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "campaign/campaign_line.hpp"
#include "campaign/campaign_operator.hpp"
#include "support/safety_judge.hpp"

namespace lb::test::campaign {

struct Found {
  std::size_t device;  // index into the line's devices
  safety::Violation violation;
};

// What the judge read: every bus's frames and every operator's requests, and the bridge's timeline.
struct Record {
  std::vector<std::vector<lb::can::CanFrame>> frames;  // per device: its bus's frames
  std::vector<std::vector<safety::OperatorRequest>> requests;
  BridgeTimeline bridge;
};

class CampaignJudge {
 public:
  CampaignJudge(CampaignLine& line, const std::vector<std::unique_ptr<CampaignOperator>>& operators)
      : line_(line), operators_(operators) {}

  // Violations found in what is recorded so far that were not reported before. Nothing written or
  // sent after the horizon is read: the oldest request still in flight (its answer may allow what
  // came after it), or the newest frame of the quietest bus less half a second (a frame may still
  // be on its way to the recorder), whichever is sooner.
  std::vector<Found> interim() {
    auto r = record();
    std::int64_t horizon = std::numeric_limits<std::int64_t>::max();
    for (const auto& frames : r.frames) horizon = std::min(horizon, frames.empty() ? 0 : frames.back().timestamp_ns);
    horizon -= 500'000'000;
    for (const auto& op : operators_) {
      if (const auto since = op->in_flight_since(); since != 0) horizon = std::min(horizon, since);
    }
    for (auto& frames : r.frames) {
      frames.erase(std::partition_point(frames.begin(), frames.end(),
                                        [horizon](const auto& f) { return f.timestamp_ns < horizon; }),
                   frames.end());
    }
    // A stop is read once its frames would be (its 100 ms, its answer) before the horizon.
    for (auto& requests : r.requests) {
      std::erase_if(requests, [horizon](const auto& q) {
        return q.written_ns >= horizon ||
               (q.stops() && (q.written_ns >= horizon - safety::kStopWithinNs || q.answered_ns >= horizon));
      });
    }
    std::vector<Found> fresh;
    for (auto& f : judge(r)) {
      if (seen_.insert({f.device, f.violation.invariant, f.violation.at_ns}).second) fresh.push_back(std::move(f));
    }
    return fresh;
  }

  // Everything recorded (the operators stopped, the bus gone on past their last request).
  Record record() {
    Record r;
    std::map<std::string, std::vector<lb::can::CanFrame>> by_bus;
    for (const auto& bus : line_.buses()) by_bus[bus] = line_.frames(bus);
    for (const auto& d : line_.devices()) r.frames.push_back(by_bus.at(d.bus));
    for (const auto& op : operators_) r.requests.push_back(op->requests());
    r.bridge = line_.timeline();
    return r;
  }
  std::vector<Found> judge(const Record& r) const {
    std::vector<Found> out;
    for (std::size_t i = 0; i < line_.devices().size(); ++i) {
      const auto judge = for_device(i, r.bridge);
      for (auto& v : judge.judge(r.frames[i], r.requests[i])) out.push_back({i, std::move(v)});
    }
    std::stable_sort(out.begin(), out.end(),
                     [](const auto& a, const auto& b) { return a.violation.at_ns < b.violation.at_ns; });
    return out;
  }
  safety::SafetyJudge for_device(std::size_t i, const BridgeTimeline& bridge) const {
    return {line_.devices()[i].device, line_.options().heartbeat_timeout_ms, line_.t0(), bridge};
  }

 private:
  CampaignLine& line_;
  const std::vector<std::unique_ptr<CampaignOperator>>& operators_;
  std::set<std::tuple<std::size_t, std::string, std::int64_t>> seen_;
};

}  // namespace lb::test::campaign
