#pragma once
// One operator per device of the campaign's line, on a thread of its own: a plan drawn from the
// seed (set the enabling level on or off, press the profile's stopping command, NMT stop and NMT
// start, now and then an NMT reset), each request at its planned moment or as soon as the one
// before was answered, through the safety table's panels (support/safety_operator.hpp), and every
// request logged as the table's judge reads it. A request goes out whatever the campaign is doing
// to the bridge: one written while the bridge is down is judged as such (safety_judge.hpp, I2).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "campaign/campaign_line.hpp"
#include "support/safety_operator.hpp"
#include "support/safety_request.hpp"

namespace lb::test::campaign {

enum class Act { enabling_on, enabling_off, press_stop, nmt_stop, nmt_start, nmt_reset };

struct PlannedAct {
  std::int64_t at_ms;  // from the campaign's start
  Act act;
};

// The operator's plan for device `index`, from the seed alone: first the enabling level on, then
// one request every 0.3-2.5 s until `until_ms`; after an NMT stop, most often an NMT start next.
inline std::vector<PlannedAct> plan_operator(std::uint64_t seed, std::size_t index, std::int64_t until_ms) {
  std::mt19937_64 rng(seed ^ (0x9E3779B97F4A7C15ull * (index + 1)));
  const auto draw_in = [&rng](std::int64_t lo, std::int64_t hi) {
    return lo + static_cast<std::int64_t>(rng() % static_cast<std::uint64_t>(hi - lo + 1));
  };
  std::vector<PlannedAct> plan;
  std::int64_t t = 2'000 + 150 * static_cast<std::int64_t>(index);
  plan.push_back({t, Act::enabling_on});
  // Weights out of 100: on 30, off 20, stopping command 20, NMT stop 10, NMT start 15, NMT reset 5.
  while (true) {
    t += draw_in(300, 2'500);
    if (t >= until_ms) break;
    const auto last = plan.back().act;
    const auto pick = draw_in(0, 99);
    Act act = pick < 30   ? Act::enabling_on
              : pick < 50 ? Act::enabling_off
              : pick < 70 ? Act::press_stop
              : pick < 80 ? Act::nmt_stop
              : pick < 95 ? Act::nmt_start
                          : Act::nmt_reset;
    if (last == Act::nmt_stop && draw_in(0, 99) < 60) act = Act::nmt_start;
    plan.push_back({t, act});
  }
  return plan;
}

class CampaignOperator {
 public:
  CampaignOperator(CampaignLine& line, std::size_t index, std::vector<PlannedAct> plan)
      : index_(index), device_(line.devices()[index].device), plan_(std::move(plan)) {
    panel_ = safety::make_panel({line.dds(), line.line(), device_});
    nmt_ = safety::detail::make_client<safety::NmtClient>(line.dds(), ddsl::line_service_path(line.line(), "nmt"),
                                                          line.line());
  }
  ~CampaignOperator() { stop(); }
  CampaignOperator(const CampaignOperator&) = delete;
  CampaignOperator& operator=(const CampaignOperator&) = delete;

  // Its panel reaches the bridge (a refused request answered): false after the deadline.
  bool warm() { return panel_->warm(); }
  void start(std::int64_t t0_ns) {
    thread_ = std::thread([this, t0_ns] { run(t0_ns); });
  }
  // Ends after the request in flight; idempotent.
  void stop() {
    {
      std::lock_guard lock(m_);
      stopping_ = true;
    }
    cv_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  const SafetyDevice& device() const { return device_; }
  std::size_t index() const { return index_; }
  std::vector<safety::OperatorRequest> requests() const {
    std::lock_guard lock(m_);
    return requests_;
  }
  // The moment the request in flight was written (0: none): the judge does not read past it yet.
  std::int64_t in_flight_since() const { return in_flight_; }

 private:
  void run(std::int64_t t0_ns) {
    const auto start = std::chrono::steady_clock::now() - std::chrono::nanoseconds(bus_now_ns() - t0_ns);
    for (const auto& p : plan_) {
      {
        std::unique_lock lock(m_);
        if (cv_.wait_until(lock, start + std::chrono::milliseconds(p.at_ms), [this] { return stopping_; })) return;
      }
      in_flight_ = bus_now_ns();
      auto r = act(p.act);
      std::lock_guard lock(m_);
      requests_.push_back(std::move(r));
      in_flight_ = 0;
    }
  }
  safety::OperatorRequest act(Act a) {
    namespace srv = linebridge_msgs::srv;
    switch (a) {
      case Act::enabling_on: return panel_->set_enabling(true);
      case Act::enabling_off: return panel_->set_enabling(false);
      case Act::press_stop: return panel_->press_stop();
      case Act::nmt_stop: return safety::nmt_request(*nmt_, device_, srv::NMT_STOP);
      case Act::nmt_start: return safety::nmt_request(*nmt_, device_, srv::NMT_START);
      case Act::nmt_reset: return safety::nmt_request(*nmt_, device_, srv::NMT_RESET_NODE);
    }
    return {};
  }

  std::size_t index_;
  const SafetyDevice& device_;
  std::vector<PlannedAct> plan_;
  std::unique_ptr<safety::OperatorPanel> panel_;
  std::unique_ptr<safety::NmtClient> nmt_;
  mutable std::mutex m_;
  std::condition_variable cv_;
  bool stopping_ = false;
  std::vector<safety::OperatorRequest> requests_;
  std::atomic<std::int64_t> in_flight_{0};
  std::thread thread_;
};

}  // namespace lb::test::campaign
