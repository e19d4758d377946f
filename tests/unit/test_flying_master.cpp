// CiA 302-2 flying master (FlyingMaster, docs/redundancy.md) on a real loop and a virtual bus whose
// other member (this test) plays the other masters: the power-up detection (73h) and negotiation
// (72h, the wait priority x priority slot + node-ID x device slot, 71h [priority, node-ID]), the
// active master's answer to 73h and its force negotiation (76h), the renegotiation that evidence of
// another active master starts, and the loser that steps back. Expected frames and waits from
// CiA 302-2's rules as the public implementations apply them (docs/redundancy.md), by hand.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <future>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "canopen/flying_master.hpp"
#include "support/eventually.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;

namespace {

constexpr std::uint8_t kNode = 1;
constexpr std::uint8_t kPriority = 2;
constexpr std::int64_t kMs = 1'000'000;

class Flying : public lb::test::LoopOnOwnBus {
 protected:
  Flying() : LoopOnOwnBus("fm") {}

  // delay 50 ms, detect 50 ms (or `detect`), slot 1000 ms, device slot 1 ms: its wait 2 x 1000 + 1 x 1 =
  // 2001 ms, long enough for this test to act within it on a loaded machine; cycle 300 ms.
  void start(std::chrono::milliseconds detect = 50ms, std::chrono::milliseconds stall = 100ms) {
    co::FlyingMaster::Settings s{kNode, kPriority, detect, 50ms, 1000ms, 1ms, 300ms, stall};
    flying_ = std::make_unique<co::FlyingMaster>(
        *loop_, s, nullptr,
        co::FlyingMaster::Callbacks{[this] {
                                      record("win");
                                      flying_->mastering();  // as the bridge does once it masters the bus
                                    },
                                    [this](std::uint8_t node) { record("stand by " + std::to_string(node)); },
                                    [this](const std::string&) { record("step back"); }});
    loop_->start();
    loop_->post([this] { flying_->start(); });
  }
  void record(std::string what) {
    std::lock_guard lock(m_);
    events_.push_back(std::move(what));
  }
  std::vector<std::string> events() {
    std::lock_guard lock(m_);
    return events_;
  }
  bool saw(const std::string& what) {
    const auto e = events();
    return std::find(e.begin(), e.end(), what) != e.end();
  }
  co::FlyingMaster::State state() {
    std::promise<co::FlyingMaster::State> done;
    loop_->post([&] { done.set_value(flying_->state()); });
    return done.get_future().get();
  }
  std::vector<lb::can::CanFrame> sent(std::uint32_t id) { return spy_->frames(id); }
  bool wait_sent(std::uint32_t id, std::size_t n = 1) {
    return lb::test::eventually(10s, [&] { return sent(id).size() >= n; });
  }
  void send(std::uint32_t id, std::initializer_list<std::uint8_t> data = {}) {
    ASSERT_TRUE(spy_->send(lb::can::make_frame(id, data)));
  }
  // Alone on the bus: it negotiates and wins.
  void become_active(std::chrono::milliseconds stall = 100ms) {
    start(50ms, stall);
    ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("win"); }));
    ASSERT_TRUE(wait_sent(0x071));
  }

  std::unique_ptr<co::FlyingMaster> flying_;
  std::mutex m_;
  std::vector<std::string> events_;
};

TEST_F(Flying, AloneAtPowerUpItAsksNegotiatesAndWinsAfterItsWait) {
  start();
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("win"); }));
  const auto ask = sent(0x073);
  const auto request = sent(0x072);
  ASSERT_TRUE(wait_sent(0x071));
  const auto answer = sent(0x071);
  ASSERT_EQ(ask.size(), 1u);
  ASSERT_EQ(request.size(), 1u);
  EXPECT_EQ(ask[0].len, 0);
  EXPECT_EQ(request[0].len, 0);
  // 72h at least the detection timeout after 73h; 71h [2, 1] at least 2001 ms after 72h.
  EXPECT_GE(request[0].timestamp_ns - ask[0].timestamp_ns, 50 * kMs);
  EXPECT_GE(answer[0].timestamp_ns - request[0].timestamp_ns, 2001 * kMs);
  ASSERT_EQ(answer[0].len, 2);
  EXPECT_EQ(answer[0].data[0], kPriority);
  EXPECT_EQ(answer[0].data[1], kNode);
  EXPECT_EQ(state(), co::FlyingMaster::State::active);
  EXPECT_FALSE(saw("stand by 1"));

  // Active: a 73h is answered with 71h; 76h comes every detection cycle (300 ms).
  send(0x073);
  ASSERT_TRUE(wait_sent(0x071, 2));
  ASSERT_TRUE(wait_sent(0x076, 2));
  const auto force = sent(0x076);
  EXPECT_GE(force[1].timestamp_ns - force[0].timestamp_ns, 250 * kMs);
  EXPECT_GE(force[0].timestamp_ns - answer[0].timestamp_ns, 250 * kMs);
}

TEST_F(Flying, AnActiveMastersAnswerMakesItStandByThatMaster) {
  start(5000ms);  // the detection waits long enough for this test to answer
  ASSERT_TRUE(wait_sent(0x073));
  send(0x071, {0, 9});
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("stand by 9"); }));
  EXPECT_EQ(state(), co::FlyingMaster::State::standing_by);
  // A standby takes no part in negotiations while it watches a live master.
  send(0x072);
  send(0x076);
  send(0x073);
  std::this_thread::sleep_for(500ms);  // stays: a 72h or 71h of its own would come within it
  EXPECT_TRUE(sent(0x072).empty());
  EXPECT_TRUE(sent(0x071).empty());
  EXPECT_FALSE(saw("win"));
}

TEST_F(Flying, TheLinesMasterHeartbeatDuringDetectionMakesItStandBy) {
  start(5000ms);
  send(0x701, {0x05});
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("stand by 1"); }));
  EXPECT_TRUE(sent(0x072).empty());
}

TEST_F(Flying, AMalformedAnswerIsIgnored) {
  start(5000ms);
  ASSERT_TRUE(wait_sent(0x073));
  send(0x071, {0});           // one byte: no node-ID
  send(0x071, {0, 9, 0x55});  // three
  send(0x701, {0x05});        // then a real sign of a master
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("stand by 1"); }));
  EXPECT_FALSE(saw("stand by 9"));
  EXPECT_FALSE(saw("stand by 0"));
}

TEST_F(Flying, InTheNegotiationABetterMasterWinsAndAWorseOneDoesNot) {
  start();
  ASSERT_TRUE(wait_sent(0x072));
  send(0x071, {3, 9});  // a worse priority: its own answer at the end of its wait decides
  send(0x071, {2, 5});  // the same priority, a higher node-ID: worse
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("win"); }));
  EXPECT_EQ(events().size(), 1u);
}

TEST_F(Flying, InTheNegotiationABetterPriorityWinsWhateverItsNodeId) {
  start();
  ASSERT_TRUE(wait_sent(0x072));
  send(0x071, {1, 40});  // a better priority, whatever its node-ID
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("stand by 40"); }));
  EXPECT_FALSE(saw("win"));
}

TEST_F(Flying, ActiveAForceNegotiationMakesItNegotiateAndABetterMasterMakesItStepBack) {
  become_active();
  send(0x076);
  ASSERT_TRUE(wait_sent(0x072, 2));  // its power-up one, and this one
  EXPECT_EQ(state(), co::FlyingMaster::State::negotiating);
  send(0x073);  // still the active master while it negotiates: it answers
  ASSERT_TRUE(wait_sent(0x071, 2));
  send(0x071, {0, 9});
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("step back"); }));
  EXPECT_EQ(state(), co::FlyingMaster::State::stepped_back);
  // Stepped back: nothing more from it, a 73h unanswered.
  const auto answers = sent(0x071).size();
  send(0x073);
  std::this_thread::sleep_for(400ms);  // stays: an answer, or a 76h of its cycle, would come within it
  EXPECT_EQ(sent(0x071).size(), answers);
  const auto forces = sent(0x076).size();
  std::this_thread::sleep_for(400ms);  // stays: one cycle
  EXPECT_EQ(sent(0x076).size(), forces);
}

TEST_F(Flying, ActiveAnotherMastersHeartbeatOnItsNodeIdStartsANegotiationItWinsAlone) {
  become_active();
  send(0x701, {0x05});
  ASSERT_TRUE(wait_sent(0x072, 2));
  ASSERT_TRUE(wait_sent(0x071, 2));  // its wait over: it says so again
  EXPECT_EQ(state(), co::FlyingMaster::State::active);
  EXPECT_FALSE(saw("step back"));
  const auto request = sent(0x072).back();
  const auto answer = sent(0x071).back();
  EXPECT_GE(answer.timestamp_ns - request.timestamp_ns, 2001 * kMs);
}

TEST_F(Flying, ActiveAWorseMastersAnswerStartsANegotiationThatItWins) {
  become_active();
  send(0x071, {7, 9});
  ASSERT_TRUE(wait_sent(0x072, 2));
  ASSERT_TRUE(wait_sent(0x071, 2));
  EXPECT_EQ(state(), co::FlyingMaster::State::active);
  EXPECT_FALSE(saw("step back"));
}

TEST_F(Flying, ActiveAfterItsLoopStalledAnotherMastersFramesMakeItStepBackWithoutANegotiation) {
  become_active();
  const auto requests = sent(0x072).size();
  // Its loop is held for 500 ms (five stall thresholds) while a worse master announces itself:
  // a standby took over meanwhile, whatever the priorities.
  std::promise<void> blocked;
  loop_->post([&] {
    blocked.set_value();
    std::this_thread::sleep_for(500ms);  // stays: the stall being tested
  });
  blocked.get_future().wait();
  std::this_thread::sleep_for(250ms);  // stays: the announcement comes well into the stall
  send(0x071, {7, 9});
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("step back"); }));
  EXPECT_EQ(sent(0x072).size(), requests) << "a negotiation instead of stepping back";
}

// The standby judged the master silent during its stall, and its 71h came a moment after the stall
// ended: the same takeover, so a step back, not a negotiation with two SYNC producers meanwhile.
TEST_F(Flying, ActiveAMastersAnswerRightAfterItsStallMakesItStepBack) {
  become_active(600ms);  // a stall threshold of 600 ms: this test's thread answers well within it, loaded or not
  const auto requests = sent(0x072).size();
  std::promise<void> blocked;
  std::promise<void> resumed;
  loop_->post([&] {
    blocked.set_value();
    std::this_thread::sleep_for(2000ms);  // stays: the stall being tested
    resumed.set_value();
  });
  blocked.get_future().wait();
  resumed.get_future().wait();
  std::this_thread::sleep_for(100ms);  // stays: the loop has run again (its tick saw the stall) when the 71h comes
  send(0x071, {7, 9});
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return saw("step back"); }));
  EXPECT_EQ(sent(0x072).size(), requests) << "a negotiation instead of stepping back";
}

}  // namespace
