// Another master is believed only on evidence a few spoofed frames cannot give: a foreign SYNC
// producer that runs (OtherMasterWatch: at least 20 SYNCs over at least 2 s, none more than
// 250 ms apart, on the frames' timestamps). Ten SYNCs and then one every 4.5 s never make the
// bridge yield the bus; a real producer at 20 ms does, within its first seconds, and the bridge
// transmits again 5 s after it stopped, a stray SYNC later not keeping it silent. Stops go out
// while it yields (BusLoop::send_stop). A real loop on a virtual bus; the other master is the
// test's own member.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <functional>
#include <future>
#include <thread>

#include "canopen/other_master.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;
using Clock = std::chrono::steady_clock;

namespace {

class OtherMaster : public lb::test::LoopOnOwnBus {
 protected:
  OtherMaster() : LoopOnOwnBus("om") {}

  void SetUp() override {
    LoopOnOwnBus::SetUp();
    watch_ = std::make_unique<co::OtherMasterWatch>(*loop_, co::OtherMasterWatch::Policy::yield, 0);
    watch_->own_sync_period(20ms);
    loop_->start();
  }

  template <class F>
  auto on_loop(F f) {
    std::promise<decltype(f())> done;
    loop_->post([&] { done.set_value(f()); });
    return done.get_future().get();
  }
  // One foreign SYNC, and the watch has seen it.
  ::testing::AssertionResult sync() {
    const auto before = on_loop([this] { return watch_->frames(); });
    if (!spy_->send(lb::can::make_frame(0x080, {}))) return ::testing::AssertionFailure() << "SYNC not sent";
    const auto end = Clock::now() + 10s;
    while (on_loop([this] { return watch_->frames(); }) == before) {
      if (Clock::now() > end) return ::testing::AssertionFailure() << "the SYNC never reached the watch";
      std::this_thread::sleep_for(1ms);
    }
    return ::testing::AssertionSuccess();
  }
  bool held() {
    return on_loop([this] { return loop_->transmission_held(); });
  }
  std::uint64_t yields() {
    return on_loop([this] { return watch_->yields(); });
  }
  // A SYNC producer at `period` for `how_long`; the time of its last SYNC.
  Clock::time_point produce(std::chrono::milliseconds period, std::chrono::milliseconds how_long) {
    const auto end = Clock::now() + how_long;
    auto last = Clock::now();
    while (Clock::now() < end) {
      EXPECT_TRUE(spy_->send(lb::can::make_frame(0x080, {})));
      last = Clock::now();
      std::this_thread::sleep_for(period);  // stays: the other producer's period
    }
    return last;
  }
  static bool eventually(const std::function<bool()>& done, std::chrono::seconds within) {
    const auto end = Clock::now() + within;
    while (!done()) {
      if (Clock::now() > end) return false;
      std::this_thread::sleep_for(10ms);
    }
    return true;
  }

  std::unique_ptr<co::OtherMasterWatch> watch_;
};

}  // namespace

// The attack of issue 40: ten spoofed SYNCs (25 ms apart: more than the old 200 ms of evidence),
// then one every 4.5 s. The bridge never yields: every frame is counted, none holds its
// transmission.
TEST_F(OtherMaster, TenSyncsThenOneEvery4_5sNeverYield) {
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(sync());
    EXPECT_FALSE(held()) << "held after SYNC " << i + 1;
    std::this_thread::sleep_for(25ms);  // stays: the spoofer's pace
  }
  for (int i = 0; i < 2; ++i) {
    std::this_thread::sleep_for(4500ms);  // stays: the spoofer's pace
    ASSERT_TRUE(sync());
    EXPECT_FALSE(held()) << "held after the SYNC " << 4.5 * (i + 1) << " s later";
  }
  EXPECT_EQ(yields(), 0u);
  EXPECT_EQ(on_loop([this] { return watch_->frames(); }), 12u);
  EXPECT_TRUE(on_loop([this] { return loop_->send(lb::can::make_frame(0x080, {})).has_value(); }))
      << "the bridge's own SYNC was refused";
}

// A real other master: SYNC every 20 ms for 3 s. The bridge yields within it (holds every
// transmission but stops: a stop goes out, anything else is refused), and transmits again 5 s
// after the producer's last SYNC.
TEST_F(OtherMaster, ARealProducerIsYieldedToAndTheBridgeResumes5sAfterItStops) {
  const auto last = produce(20ms, 3000ms);
  ASSERT_TRUE(eventually([&] { return held(); }, 10s)) << "a SYNC producer running for 3 s was not yielded to";
  EXPECT_EQ(yields(), 1u);
  EXPECT_FALSE(on_loop([this] { return loop_->send(lb::can::make_frame(0x205, {0})).has_value(); }))
      << "an RPDO went out beside the other master";
  EXPECT_TRUE(on_loop([this] {
    return loop_->send_stop(lb::can::make_frame(0x000, {0x02, 5})).has_value();
  })) << "a stop was refused while yielding";
  EXPECT_TRUE(spy_->wait_until([](const std::vector<lb::can::CanFrame>& f) {
    return std::any_of(f.begin(), f.end(), [](const auto& x) { return x.id == 0x000 && x.data[0] == 0x02; });
  })) << "the stop never reached the bus";
  ASSERT_TRUE(eventually([&] { return !held(); }, 30s)) << "the bridge never transmitted again";
  const auto resumed_after = Clock::now() - last;
  EXPECT_GE(resumed_after, 4900ms) << "resumed before the other master was silent for 5 s";
  EXPECT_LT(resumed_after, 9s);
}

// A SYNC 4.5 s after the producer stopped is no run: it does not keep the bridge silent, which
// transmits again 5 s after the producer's last SYNC, not 5 s after the stray one.
TEST_F(OtherMaster, AStraySyncDoesNotKeepTheYield) {
  const auto last = produce(20ms, 3000ms);
  ASSERT_TRUE(eventually([&] { return held(); }, 10s));
  std::this_thread::sleep_until(last + 4500ms);  // stays: when the stray SYNC comes
  ASSERT_TRUE(sync());
  ASSERT_TRUE(eventually([&] { return !held(); }, 30s)) << "the bridge never transmitted again";
  const auto resumed_after = Clock::now() - last;
  EXPECT_LT(resumed_after, 8s) << "a stray SYNC kept the bridge silent";
  EXPECT_EQ(yields(), 1u);
}
