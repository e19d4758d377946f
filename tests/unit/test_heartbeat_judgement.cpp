// A heartbeat timeout is judged on the bus's own time (HeartbeatConsumer, through RemoteNode):
// when the bus loop was held up (its process stopped, a slow handler), the heartbeats that came
// meanwhile wait in its queue while its timer has already expired; they are read before the
// device is judged, so a stalled bridge does not declare every device lost and boot them all
// again. A device that is really silent is still declared lost: on a quiet bus, after a stall
// while others keep sending, and on a bus flooded by other frames (always readable).
//
// A real bus loop on a virtual bus; the device is the test's own member sending heartbeats
// (state operational, every 50 ms; heartbeat timeout 300 ms, CiA 301 1016h consumer time).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <future>
#include <mutex>
#include <thread>
#include <vector>

#include "canopen/node_driver.hpp"
#include "canopen/remote_node.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::uint8_t kNode = 9;
constexpr std::uint8_t kOperational = 0x05;
constexpr auto kTimeout = 300ms;

// What the node tells its drivers: when it went offline, and the lost events.
class Watch final : public co::NodeDriver {
 public:
  void on_nmt_change(co::NmtState, bool online) noexcept override {
    std::lock_guard lock(m_);
    if (!online) offline_at_.push_back(Clock::now());
  }
  void on_event(co::NodeEvent e) noexcept override {
    if (e == co::NodeEvent::lost) ++lost_;
  }
  std::vector<Clock::time_point> offline_at() {
    std::lock_guard lock(m_);
    return offline_at_;
  }
  int lost() const { return lost_; }

 private:
  std::mutex m_;
  std::vector<Clock::time_point> offline_at_;
  std::atomic<int> lost_{0};
};

class HeartbeatJudgement : public lb::test::LoopOnOwnBus {
 protected:
  HeartbeatJudgement() : LoopOnOwnBus("hbj") {}

  void SetUp() override {
    LoopOnOwnBus::SetUp();
    node_ = std::make_unique<co::RemoteNode>(*loop_, kNode, kTimeout, true);
    node_->attach(watch_);
    loop_->start();
  }
  void TearDown() override {
    stop_heartbeats();
    stop_flood();
    LoopOnOwnBus::TearDown();
  }

  // The device: its heartbeat every 50 ms until stop_heartbeats().
  void start_heartbeats() {
    beating_ = std::jthread([this](std::stop_token stop) {
      while (!stop.stop_requested()) {
        last_beat_ = Clock::now().time_since_epoch().count();  // before: the master's timer starts later
        (void)spy_->send(lb::can::make_frame(0x700 + kNode, {kOperational}));
        std::this_thread::sleep_for(50ms);
      }
    });
  }
  void stop_heartbeats() {
    if (!beating_.joinable()) return;
    beating_.request_stop();
    beating_.join();
  }
  // Others on the bus: a TPDO of another node every `every`, until stop_flood().
  void start_other_traffic(std::chrono::microseconds every) {
    flood_ = std::jthread([this, every](std::stop_token stop) {
      for (std::uint8_t i = 0; !stop.stop_requested(); ++i) {
        (void)spy_->send(lb::can::make_frame(0x18A, {i, 0, 0, 0}));
        ++other_frames_;
        std::this_thread::sleep_for(every);
      }
    });
  }
  void stop_flood() {
    if (!flood_.joinable()) return;
    flood_.request_stop();
    flood_.join();
  }
  template <class F>
  auto on_loop(F f) {
    std::promise<decltype(f())> done;
    loop_->post([&] { done.set_value(f()); });
    return done.get_future().get();
  }
  bool online() {
    return on_loop([this] { return node_->online(); });
  }
  std::uint64_t deferred() {
    return on_loop([this] { return node_->heartbeat_judgements_deferred(); });
  }
  // The loop thread held up for `how_long` (what SIGSTOP of the bus process does to it).
  void stall(std::chrono::milliseconds how_long) {
    std::promise<void> holding;
    loop_->post([&holding, how_long] {
      holding.set_value();
      std::this_thread::sleep_for(how_long);
    });
    holding.get_future().wait();
  }
  static bool eventually(const std::function<bool()>& done, std::chrono::seconds within = 10s) {
    const auto end = Clock::now() + within;
    while (!done()) {
      if (Clock::now() > end) return false;
      std::this_thread::sleep_for(10ms);
    }
    return true;
  }

  std::unique_ptr<co::RemoteNode> node_;
  Watch watch_;
  std::jthread beating_;
  std::jthread flood_;
  std::atomic<std::uint64_t> other_frames_{0};
  std::atomic<Clock::rep> last_beat_{0};  // when the device last sent its heartbeat
};

}  // namespace

// The loop held up for 1 s (over three heartbeat timeouts) while the device keeps sending its
// heartbeat: the heartbeats queued meanwhile are read before the timeout is judged, so the device
// is never declared lost.
TEST_F(HeartbeatJudgement, HeartbeatsQueuedWhileTheLoopWasHeldUpAreReadBeforeTheTimeoutIsJudged) {
  start_heartbeats();
  ASSERT_TRUE(eventually([&] { return online(); }));
  stall(1000ms);
  // Once the loop runs again: the judgement that was due waited for the queued frames.
  ASSERT_TRUE(eventually([&] { return deferred() >= 1; })) << "the timeout was never due: the test proves nothing";
  std::this_thread::sleep_for(3 * kTimeout);  // stays: the window in which a wrong loss would show
  EXPECT_TRUE(online());
  EXPECT_EQ(watch_.lost(), 0) << "a device whose heartbeats were queued was declared lost";
  EXPECT_TRUE(watch_.offline_at().empty());
}

// A device that falls silent on a quiet bus is lost one heartbeat timeout after its last
// heartbeat, as before: nothing is queued, nothing to wait for.
TEST_F(HeartbeatJudgement, ARealSilenceIsLost) {
  start_heartbeats();
  ASSERT_TRUE(eventually([&] { return online(); }));
  stop_heartbeats();
  const Clock::time_point silent_from{Clock::duration{last_beat_.load()}};
  ASSERT_TRUE(eventually([&] { return watch_.lost() == 1; })) << "a silent device was never declared lost";
  const auto offline = watch_.offline_at();
  ASSERT_EQ(offline.size(), 1u);
  EXPECT_GE(offline.front() - silent_from, kTimeout) << "lost before its timeout";
  EXPECT_FALSE(online());
}

// The device falls silent, then the loop is held up while other nodes keep sending: after the
// stall the queued frames, stamped after the device's deadline without a heartbeat of it, prove
// the loss: it is declared lost, although the judgement waited for them.
TEST_F(HeartbeatJudgement, ASilenceDuringAStallIsLostOnceTheQueuedFramesProveIt) {
  start_heartbeats();
  ASSERT_TRUE(eventually([&] { return online(); }));
  start_other_traffic(20ms);
  stop_heartbeats();
  stall(1000ms);
  ASSERT_TRUE(eventually([&] { return watch_.lost() == 1; })) << "a device silent through a stall was never lost";
  EXPECT_GE(deferred(), 1u) << "the judgement did not wait for the queued frames: the test proves nothing";
  EXPECT_FALSE(online());
}

// A bus flooded by other frames is always readable: the judgement still ends, by the frames'
// timestamps (one stamped after the deadline, no heartbeat before it), while the flood goes on.
TEST_F(HeartbeatJudgement, AFloodedBusStillJudgesATimeout) {
  start_heartbeats();
  ASSERT_TRUE(eventually([&] { return online(); }));
  start_other_traffic(50us);
  ASSERT_TRUE(eventually([&] { return other_frames_ > 1000; })) << "no flood";
  stop_heartbeats();
  ASSERT_TRUE(eventually([&] { return watch_.lost() == 1; })) << "a silent device on a flooded bus was never lost";
  // The flood was still on when the loss was judged: it goes on after it.
  const auto during = other_frames_.load();
  EXPECT_TRUE(eventually([&] { return other_frames_.load() > during + 100; })) << "the flood had stopped";
}
