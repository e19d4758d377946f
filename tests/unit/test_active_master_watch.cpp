// A standby's watch on the master (ActiveMasterWatch, docs/redundancy.md), on a real loop and a
// virtual bus whose other member (this test) plays the master: its heartbeat on 700h + the
// master's node-ID keeps the standby standing by; silent for takeover_after, the standby takes
// over once, knowing whether a master was heard, when its last heartbeat and SYNC were, and the
// last NMT command it sent each node (to the node, or to all). A loop held up while the master's
// heartbeats came (its thread stopped) reads them before it judges: no takeover. The watch stands by
// the master the negotiation named (FlyingMaster): another node-ID's heartbeat keeps it standing by
// then; a negotiation won takes over at once (claim).
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <optional>
#include <thread>

#include "canopen/active_master_watch.hpp"
#include "support/eventually.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;

namespace {

constexpr std::uint8_t kMaster = 1;

class ActiveMaster : public lb::test::LoopOnOwnBus {
 protected:
  ActiveMaster() : LoopOnOwnBus("amw") {}

  void start(std::chrono::milliseconds after, std::uint8_t active = kMaster) {
    watch_ = std::make_unique<co::ActiveMasterWatch>(*loop_, kMaster, after, [this](const auto& t) {
      std::lock_guard lock(m_);
      takeovers_.push_back(t);
    });
    loop_->start();
    loop_->post([this, active] { watch_->stand_by(active); });
  }
  template <class F>
  auto on_loop(F f) {
    std::promise<decltype(f())> done;
    loop_->post([&] { done.set_value(f()); });
    return done.get_future().get();
  }
  std::vector<co::ActiveMasterWatch::Takeover> takeovers() {
    std::lock_guard lock(m_);
    return takeovers_;
  }
  void beat() { ASSERT_TRUE(spy_->send(lb::can::make_frame(0x700 + kMaster, {0x05}))); }

  std::unique_ptr<co::ActiveMasterWatch> watch_;
  std::mutex m_;
  std::vector<co::ActiveMasterWatch::Takeover> takeovers_;
};

TEST_F(ActiveMaster, AnActiveMasterThatNeverBeatsIsTakenOverAfterTheWait) {
  const auto t0 = std::chrono::steady_clock::now();
  start(100ms);
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return !takeovers().empty(); }));
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 100ms);
  EXPECT_FALSE(takeovers().front().master_heard);
  EXPECT_TRUE(on_loop([&] { return watch_->active(); }));
  EXPECT_NE(on_loop([&] { return watch_->describe(); }).find("mastered from its start"), std::string::npos);
}

TEST_F(ActiveMaster, ANegotiationWonTakesOverAtOnceAndOnlyOnce) {
  start(10s);
  on_loop([&] {
    watch_->claim();
    return 0;
  });
  ASSERT_EQ(takeovers().size(), 1u);
  EXPECT_FALSE(takeovers().front().master_heard);
  on_loop([&] {
    watch_->claim();
    return 0;
  });
  EXPECT_EQ(takeovers().size(), 1u);
}

TEST_F(ActiveMaster, TheMasterTheNegotiationNamedIsTheOneWatched) {
  start(300ms, 9);  // a foreign flying master, node 9
  for (int i = 0; i < 20; ++i) {
    ASSERT_TRUE(spy_->send(lb::can::make_frame(0x709, {0x05})));
    std::this_thread::sleep_for(50ms);  // stays: the master's heartbeat period
  }
  EXPECT_TRUE(takeovers().empty());
  // The line's own master node-ID beating does not stand for node 9.
  for (int i = 0; i < 20 && takeovers().empty(); ++i) {
    beat();
    std::this_thread::sleep_for(50ms);  // stays: the heartbeat period
  }
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return !takeovers().empty(); }));
  EXPECT_TRUE(takeovers().front().master_heard);
}

TEST_F(ActiveMaster, TheMastersHeartbeatKeepsItStandingByAndItsSilenceMakesOneTakeover) {
  start(300ms);  // six heartbeat periods: a loaded machine's late sleep is no silence
  // Heartbeats every 50 ms for a second: never a takeover.
  for (int i = 0; i < 20; ++i) {
    beat();
    if (i == 10) {
      ASSERT_TRUE(spy_->send(lb::can::make_frame(0x080, {})));
    }
    std::this_thread::sleep_for(50ms);  // stays: the master's heartbeat period
  }
  EXPECT_TRUE(takeovers().empty());
  EXPECT_FALSE(on_loop([&] { return watch_->active(); }));
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return !takeovers().empty(); }));
  const auto t = takeovers().front();
  EXPECT_TRUE(t.master_heard);
  EXPECT_NE(t.last_sync_ns, 0);
  EXPECT_GE(t.at_ns - t.last_heartbeat_ns, 300'000'000);
  // Heartbeats after the takeover change nothing: one takeover per run.
  beat();
  std::this_thread::sleep_for(300ms);  // stays: a second takeover would come within it
  EXPECT_EQ(takeovers().size(), 1u);
}

TEST_F(ActiveMaster, TheMastersLastNmtCommandPerNodeIsKept) {
  start(10s);
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x000, {0x01, 0x00})));  // start all
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x000, {0x02, 0x05})));  // stop node 5
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x000, {0x80, 0x07})));  // node 7 pre-operational
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x000, {0x02})));        // malformed: ignored
  ASSERT_TRUE(lb::test::eventually(10s, [&] {
    return on_loop([&] { return watch_->last_command(7); }) == co::NmtCommand::enter_pre_operational;
  }));
  EXPECT_EQ(on_loop([&] { return watch_->last_command(5); }), co::NmtCommand::stop);
  EXPECT_EQ(on_loop([&] { return watch_->last_command(3); }), co::NmtCommand::start);
  EXPECT_EQ(on_loop([&] { return watch_->last_command(0); }), std::nullopt);
}

TEST_F(ActiveMaster, ALoopHeldUpReadsTheHeartbeatsThatCameBeforeItJudges) {
  start(300ms);
  beat();
  // The loop's thread is held for 800 ms (a task that blocks it) while the master beats on: the
  // wait runs out meanwhile, and the heartbeats queued on the bus must be read before it judges.
  std::promise<void> blocked;
  loop_->post([&] {
    blocked.set_value();
    std::this_thread::sleep_for(800ms);  // stays: the stall being tested
  });
  blocked.get_future().wait();
  for (int i = 0; i < 24; ++i) {
    beat();
    std::this_thread::sleep_for(50ms);  // stays: the master's heartbeat period
  }
  EXPECT_TRUE(takeovers().empty()) << "a takeover while the master's heartbeats waited to be read";
}

}  // namespace
