// What refuses a stop asks RemoteNode::heard_now(): heard, counting the frames that wait on the
// bus (BusLoop::catch_up). A request decided on the loop thread in the same instant as the
// device's first frame after a silence must not be refused as "not heard" because that frame was
// still in the socket (the fault campaign, feeders +1131.736 s). A real loop on a virtual bus; the
// device is this test's own bus member.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <thread>

#include "canopen/remote_node.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;

namespace {

class HeardNow : public lb::test::LoopOnOwnBus {
 protected:
  HeardNow() : LoopOnOwnBus("hn") {}
  void SetUp() override {
    LoopOnOwnBus::SetUp();
    node_ = std::make_unique<co::RemoteNode>(*loop_, 5, 300ms, true);
    loop_->start();
  }
  // On the loop thread: the device's heartbeat is sent and reaches the loop's socket while the
  // loop is busy here; then what heard() and heard_now() say.
  std::pair<bool, bool> decide_as_the_heartbeat_arrives() {
    std::promise<std::pair<bool, bool>> result;
    loop_->post([&] {
      EXPECT_TRUE(spy_->send(lb::can::make_frame(0x705, {0x05})));
      const auto end = std::chrono::steady_clock::now() + 5s;
      while (!loop_->input_pending() && std::chrono::steady_clock::now() < end) std::this_thread::yield();
      const bool before = node_->heard();
      result.set_value({before, node_->heard_now()});
    });
    return result.get_future().get();
  }
  std::unique_ptr<co::RemoteNode> node_;
};

TEST_F(HeardNow, AFrameWaitingOnTheBusIsReadBeforeTheDeviceIsCalledNotHeard) {
  const auto [heard, heard_now] = decide_as_the_heartbeat_arrives();
  EXPECT_FALSE(heard) << "the heartbeat was read before the decision: the test proves nothing";
  EXPECT_TRUE(heard_now);
}

TEST_F(HeardNow, NothingWaitingAndNothingHeardIsNotHeard) {
  std::promise<bool> result;
  loop_->post([&] { result.set_value(node_->heard_now()); });
  EXPECT_FALSE(result.get_future().get());
}

TEST_F(HeardNow, DuringDispatchTheLoopDoesNotReadAgain) {
  std::promise<bool> caught_up;
  loop_->on_frame(0x181, [&](const lb::can::CanFrame&) { caught_up.set_value(loop_->catch_up()); });
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x181, {0x01})));
  EXPECT_FALSE(caught_up.get_future().get());
}

}  // namespace
