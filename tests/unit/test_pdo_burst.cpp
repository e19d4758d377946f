// One status sample per burst of PDOs (BusLoop flushes + PdoBurst), or per SYNC cycle
// (CycleDeadline), on a real bus loop over a virtual bus, with frames injected by a second bus
// member.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/cycle_deadline.hpp"
#include "gateways/node/pdo_burst.hpp"
#include "support/bus_spy.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
using lb::canopen::BusLoop;
using lb::gateways::PdoBurst;

namespace {

constexpr std::uint32_t kTpdo1 = 0x181;
constexpr std::uint32_t kTpdo2 = 0x281;

// What a gateway would publish: the PDO values it had decoded when it published.
struct Sample {
  std::vector<std::uint8_t> values;  // the first data byte of every PDO decoded so far, by index
  std::int64_t stamp_ns;
};

class Burst : public lb::test::LoopOnOwnBus {
 protected:
  Burst() : LoopOnOwnBus("burst") {}
  void SetUp() override {
    LoopOnOwnBus::SetUp();
    if (per_cycle_) {
      cycle_ = std::make_unique<lb::canopen::CycleDeadline>(*loop_, 200ms);
      loop_->on_frame(0x080, [this](const lb::can::CanFrame&) { cycle_->seen(); });
    }
    burst_ = std::make_unique<PdoBurst>(*loop_, cycle_.get(), [this](std::int64_t stamp) { publish(stamp); });
    loop_->on_frame(kTpdo1, [this](const lb::can::CanFrame& f) { on_pdo(0, f); });
    loop_->on_frame(kTpdo2, [this](const lb::can::CanFrame& f) { on_pdo(1, f); });
    loop_->start();
  }

  // As SawGateway::on_pdo: admit, decode, add.
  void on_pdo(std::size_t index, const lb::can::CanFrame& f) {
    burst_->admit(index);
    image_[index] = f.data[0];
    // Both are synchronous TPDOs sent at every SYNC (transmission type 1), as a saw's.
    burst_->add(index, f.timestamp_ns, [] { return PdoBurst::Timing{true, 0b11}; });
  }
  void publish(std::int64_t stamp) {
    burst_->published();
    std::lock_guard lock(m_);
    samples_.push_back({{image_[0], image_[1]}, stamp});
  }

  void send(std::uint32_t id, std::uint8_t value) {
    lb::can::CanFrame f;
    f.id = id;
    f.len = 1;
    f.data[0] = value;
    ASSERT_TRUE(spy_->send(f));
  }
  // Holds the loop thread while `inject` sends, so that everything sent arrives as one burst.
  void as_one_burst(const std::function<void()>& inject) {
    std::promise<void> release;
    std::promise<void> holding;
    loop_->post([&] {
      holding.set_value();
      release.get_future().wait();
    });
    holding.get_future().wait();
    inject();
    std::this_thread::sleep_for(100ms);  // through the hub into the loop's socket
    release.set_value();
    std::this_thread::sleep_for(100ms);
  }
  std::vector<Sample> samples() {
    std::lock_guard lock(m_);
    return samples_;
  }

  bool per_cycle_ = false;  // set before SetUp
  std::unique_ptr<lb::canopen::CycleDeadline> cycle_;
  std::unique_ptr<PdoBurst> burst_;
  std::array<std::uint8_t, 2> image_{};  // loop thread
  std::mutex m_;
  std::vector<Sample> samples_;
};

TEST_F(Burst, DifferentPdosOfOneBurstMakeOneSample) {
  as_one_burst([&] {
    send(kTpdo1, 11);
    send(kTpdo2, 21);
  });
  const auto s = samples();
  ASSERT_EQ(s.size(), 1U);
  EXPECT_EQ(s[0].values, (std::vector<std::uint8_t>{11, 21}));
  EXPECT_GT(s[0].stamp_ns, 0);
}

TEST_F(Burst, APdoAgainInTheBurstPublishesTheWaitingOneFirst) {
  as_one_burst([&] {
    send(kTpdo1, 11);
    send(kTpdo2, 21);
    send(kTpdo1, 12);
    send(kTpdo1, 13);
  });
  const auto s = samples();
  // Every value of TPDO1 was published once: 11 with 21, then 12, then 13 at the burst's end.
  ASSERT_EQ(s.size(), 3U);
  EXPECT_EQ(s[0].values, (std::vector<std::uint8_t>{11, 21}));
  EXPECT_EQ(s[1].values, (std::vector<std::uint8_t>{12, 21}));
  EXPECT_EQ(s[2].values, (std::vector<std::uint8_t>{13, 21}));
  EXPECT_LE(s[0].stamp_ns, s[1].stamp_ns);
  EXPECT_LE(s[1].stamp_ns, s[2].stamp_ns);
}

TEST_F(Burst, AQuietBusPublishesEveryFrame) {
  for (std::uint8_t v = 1; v <= 5; ++v) {
    send(v % 2 != 0 ? kTpdo1 : kTpdo2, v);
    std::this_thread::sleep_for(30ms);
  }
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(samples().size(), 5U);
}

TEST_F(Burst, ALongBurstOfOnePdoLosesNoValue) {
  const int frames = 3 * BusLoop::kBurstFrames;
  as_one_burst([&] {
    for (int i = 0; i < frames; ++i) send(kTpdo2, static_cast<std::uint8_t>(i));
  });
  // One PDO again and again: each value goes out, none is overwritten.
  const auto s = samples();
  ASSERT_EQ(s.size(), static_cast<std::size_t>(frames));
  for (int i = 0; i < frames; ++i) EXPECT_EQ(s[static_cast<std::size_t>(i)].values[1], static_cast<std::uint8_t>(i));
}

TEST_F(Burst, AFlushRequestedOutsideABurstRunsAtOnce) {
  std::promise<std::size_t> seen;
  loop_->post([&] {
    burst_->add(0, 42, [] { return PdoBurst::Timing{}; });  // e.g. a PDO decoded on behalf of a posted task
    seen.set_value(samples().size());
  });
  EXPECT_EQ(seen.get_future().get(), 1U);
  EXPECT_EQ(samples()[0].stamp_ns, 42);
}

// status_publish per_cycle: after a SYNC the sample waits for the device's other TPDO of the cycle.
class Cycle : public Burst {
 protected:
  Cycle() { per_cycle_ = true; }
  bool wait_samples(std::size_t n) {
    return lb::test::eventually(10s, [&] { return samples().size() >= n; });
  }
};

TEST_F(Cycle, TheTwoTpdosOfACycleMakeOneSampleThoughTheyCameApart) {
  for (std::uint8_t c = 1; c <= 2; ++c) {
    // SYNCs 200 ms apart: the deadline, the interval measured, stays 200 ms.
    const auto next = std::chrono::steady_clock::now() + 200ms;
    send(0x080, 0);
    send(kTpdo1, static_cast<std::uint8_t>(10 + c));
    std::this_thread::sleep_for(30ms);  // stays: another burst, well within the cycle's 200 ms deadline
    send(kTpdo2, static_cast<std::uint8_t>(20 + c));
    ASSERT_TRUE(wait_samples(c));
    std::this_thread::sleep_until(next);  // stays: the SYNC period the test plays
  }
  const auto s = samples();
  ASSERT_EQ(s.size(), 2U);
  EXPECT_EQ(s[0].values, (std::vector<std::uint8_t>{11, 21}));
  EXPECT_EQ(s[1].values, (std::vector<std::uint8_t>{12, 22}));
}

TEST_F(Cycle, APdoAgainWithinTheCyclePublishesTheWaitingOneFirst) {
  send(0x080, 0);
  send(kTpdo1, 11);
  send(kTpdo1, 12);
  send(kTpdo2, 21);
  ASSERT_TRUE(wait_samples(2));
  const auto s = samples();
  ASSERT_EQ(s.size(), 2U);
  EXPECT_EQ(s[0].values, (std::vector<std::uint8_t>{11, 0}));
  EXPECT_EQ(s[1].values, (std::vector<std::uint8_t>{12, 21}));
}

TEST_F(Cycle, AMissingTpdoHoldsTheOtherUntilTheDeadlineOnly) {
  send(0x080, 0);
  const auto sent = std::chrono::steady_clock::now();
  send(kTpdo1, 11);
  ASSERT_TRUE(wait_samples(1));
  // The deadline is the configured 200 ms (one SYNC seen, no interval measured yet).
  EXPECT_GE(std::chrono::steady_clock::now() - sent, 190ms) << "published before the cycle's deadline";
  EXPECT_EQ(samples()[0].values, (std::vector<std::uint8_t>{11, 0}));
}

TEST_F(Cycle, WithNoSyncHeardEachPdoGoesPerBurst) {
  send(kTpdo1, 11);
  ASSERT_TRUE(wait_samples(1));
  std::this_thread::sleep_for(30ms);
  send(kTpdo2, 21);
  ASSERT_TRUE(wait_samples(2));
  EXPECT_EQ(samples()[1].values, (std::vector<std::uint8_t>{11, 21}));
}

}  // namespace
