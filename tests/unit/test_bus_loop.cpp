// The bus loop's barrier: a handler, timer or posted task that throws is counted while the loop
// goes on, and a handler or timer that keeps throwing ends the loop through its failure handler; a
// flooded bus does not starve the timers; held transmission sends nothing; a flood of requests is
// refused beyond the queue's limit, and counted. A real loop over a virtual bus, with a second
// member that sends and watches.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <functional>
#include <future>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "can/detail.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/sync_producer.hpp"
#include "support/bus_spy.hpp"

using namespace std::chrono_literals;
using lb::canopen::BusLoop;

namespace {

class Loop : public ::testing::Test {
 protected:
  void SetUp() override {
    uri_ = "virtual:loop-" + std::to_string(::getpid()) + "-" +
           ::testing::UnitTest::GetInstance()->current_test_info()->name();
    spy_ = std::make_unique<lb::test::BusSpy>(uri_);
    loop_ = std::make_unique<BusLoop>(lb::can::open_bus(uri_).value());
  }
  void TearDown() override { loop_->stop(); }

  template <class F>
  auto on_loop(F f) {
    std::promise<decltype(f())> done;
    loop_->post([&] {
      if constexpr (std::is_void_v<decltype(f())>) {
        f();
        done.set_value();
      } else {
        done.set_value(f());
      }
    });
    return done.get_future().get();
  }
  static bool eventually(const std::function<bool()>& cond, std::chrono::milliseconds limit = 3000ms) {
    const auto end = std::chrono::steady_clock::now() + limit;
    while (!cond()) {
      if (std::chrono::steady_clock::now() > end) return false;
      std::this_thread::sleep_for(5ms);
    }
    return true;
  }

  std::string uri_;
  std::unique_ptr<lb::test::BusSpy> spy_;
  std::unique_ptr<BusLoop> loop_;
};

}  // namespace

// A handler that throws now and then is counted and logged; the loop, the handler itself and its
// neighbours go on. Sporadic throws never add up: only throws in a row count toward the limit.
TEST_F(Loop, SporadicThrowsAreCountedAndTheHandlerAndTheRestGoOn) {
  constexpr int kFrames = 4 * static_cast<int>(BusLoop::kMaxHandlerFailures);
  std::atomic<int> calls{0}, handled{0}, same_id_healthy{0}, healthy{0};
  std::atomic<bool> failed{false};
  loop_->on_failure([&](const std::string&) { failed = true; });
  loop_->on_frame(0x185, [&](const lb::can::CanFrame& f) {
    ++calls;
    if (f.data[0] % 2 == 1) throw std::runtime_error("decoder bug on odd values");
    ++handled;
  });
  loop_->on_frame(0x185, [&](const lb::can::CanFrame&) { ++same_id_healthy; });
  loop_->on_frame(0x285, [&](const lb::can::CanFrame&) { ++healthy; });
  loop_->start();
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_TRUE(spy_->send(lb::can::make_frame(0x185, {static_cast<std::uint8_t>(i)})));
    ASSERT_TRUE(spy_->send(lb::can::make_frame(0x285, {3})));
  }
  ASSERT_TRUE(eventually([&] { return healthy == kFrames && same_id_healthy == kFrames; }));
  // Every frame reached the handler, although it threw more than kMaxHandlerFailures times in all.
  EXPECT_EQ(calls, kFrames);
  EXPECT_EQ(handled, kFrames / 2);
  EXPECT_EQ(on_loop([&] { return loop_->handler_failures(); }), static_cast<std::uint64_t>(kFrames / 2));
  EXPECT_EQ(on_loop([&] { return loop_->handlers_disabled(); }), 0u);
  EXPECT_FALSE(failed);
}

// A frame handler that keeps throwing is not switched off while the loop runs on (the loop would
// still feed the service watchdog with, say, no heartbeat supervision): the loop ends through its
// failure path, so the process exits and its service manager restarts it.
TEST_F(Loop, AFrameHandlerThatKeepsThrowingEndsTheLoopThroughItsFailureHandler) {
  std::atomic<int> thrower_calls{0};
  std::promise<std::string> failure;
  auto failed = failure.get_future();
  loop_->on_failure([&](const std::string& why) { failure.set_value(why); });
  loop_->on_frame(0x185, [&](const lb::can::CanFrame&) {
    ++thrower_calls;
    throw std::runtime_error("decoder bug");
  });
  loop_->start();
  for (int i = 0; i < 25; ++i) ASSERT_TRUE(spy_->send(lb::can::make_frame(0x185, {1, 2})));
  ASSERT_EQ(failed.wait_for(5s), std::future_status::ready) << "the loop went on with a handler that always throws";
  const std::string why = failed.get();
  EXPECT_NE(why.find("185h"), std::string::npos) << why;
  EXPECT_NE(why.find("decoder bug"), std::string::npos) << why;
  EXPECT_EQ(thrower_calls, static_cast<int>(BusLoop::kMaxHandlerFailures));
  // The loop has ended: it no longer wakes, so a service watchdog fed by iterations() stops.
  const auto iterations = loop_->iterations();
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x185, {1, 2})));
  std::promise<void> ran;
  loop_->post([&] { ran.set_value(); });
  EXPECT_EQ(ran.get_future().wait_for(300ms), std::future_status::timeout) << "the loop still runs posted work";
  EXPECT_EQ(loop_->iterations(), iterations);
  EXPECT_EQ(thrower_calls, static_cast<int>(BusLoop::kMaxHandlerFailures));
}

// The same for a timer (the SYNC producer, heartbeat supervision, the SDO timeouts): a timer that
// always throws ends the loop instead of being disarmed. A posted task that throws is one-shot
// work: counted, and the loop goes on.
TEST_F(Loop, ATimerThatKeepsThrowingEndsTheLoopAndAThrowingTaskDoesNot) {
  std::atomic<int> bad_timer{0}, good_timer{0}, after_bad_task{0};
  std::promise<std::string> failure;
  auto failed = failure.get_future();
  loop_->on_failure([&](const std::string& why) { failure.set_value(why); });
  const auto good = loop_->create_timer([&] { ++good_timer; });
  loop_->arm_timer(good, 1ms, 1ms);
  loop_->start();
  loop_->post([] { throw std::logic_error("posted bug"); });
  loop_->post([&] { ++after_bad_task; });
  ASSERT_TRUE(eventually([&] { return good_timer > 20 && after_bad_task == 1; }));
  EXPECT_EQ(on_loop([&] { return loop_->handler_failures(); }), 1u);
  EXPECT_EQ(failed.wait_for(0s), std::future_status::timeout) << "a throwing posted task ended the loop";
  on_loop([&] {
    const auto bad = loop_->create_timer([&] {
      ++bad_timer;
      throw 42;  // not even a std::exception
    });
    loop_->arm_timer(bad, 1ms, 1ms);
  });
  ASSERT_EQ(failed.wait_for(5s), std::future_status::ready) << "the loop went on with a timer that always throws";
  EXPECT_NE(failed.get().find("not a std::exception"), std::string::npos);
  EXPECT_EQ(bad_timer, static_cast<int>(BusLoop::kMaxHandlerFailures));
  const int good_seen = good_timer;
  std::promise<void> ran;
  loop_->post([&] { ran.set_value(); });
  EXPECT_EQ(ran.get_future().wait_for(300ms), std::future_status::timeout) << "the loop still runs";
  EXPECT_EQ(good_timer, good_seen);
}

TEST_F(Loop, AFloodDoesNotStarveTheTimers) {
  // A flood faster than the handlers: each frame costs 20 us, and the frames arrive back to back.
  // The first frame arms a timer due at once; it must run between that frame and the next ones
  // (a SYNC waits for no burst), not after the burst or the flood.
  constexpr int kFlood = 5000;
  std::atomic<int> frames{0};
  std::atomic<int> frames_when_timer_ran{-1};
  BusLoop::TimerId t{};
  t = loop_->create_timer([&] {
    if (frames_when_timer_ran < 0) frames_when_timer_ran = frames.load();
  });
  loop_->on_frame(0x181, [&](const lb::can::CanFrame&) {
    if (frames++ == 0) loop_->arm_timer(t, 1ns);
    const auto until = std::chrono::steady_clock::now() + 20us;
    while (std::chrono::steady_clock::now() < until) {
    }
  });
  loop_->start();
  // The spy's socket refuses a frame when its buffer is full: try again (no ASSERT here: returning
  // early would leave the loop running handlers that use this function's variables).
  for (int i = 0; i < kFlood; ++i) {
    while (!spy_->send(lb::can::make_frame(0x181, {static_cast<std::uint8_t>(i)}))) std::this_thread::sleep_for(50us);
  }
  // The virtual bus drops what a slow member's queue cannot hold, as a CAN controller's overrun
  // does: wait until the loop is through with what reached it.
  int last = -1;
  while (frames != last) {
    last = frames;
    std::this_thread::sleep_for(300ms);
  }
  ASSERT_GT(frames, 4 * BusLoop::kFramesPerWake) << "no flood reached the loop: the test proves nothing";
  ASSERT_GE(frames_when_timer_ran, 0);
  EXPECT_LE(frames_when_timer_ran, 3) << "the timer waited for a burst or the flood (" << frames << " frames in all)";
}

TEST_F(Loop, HeldTransmissionSendsNothing) {
  loop_->start();
  const auto frame = lb::can::make_frame(0x080, {});
  EXPECT_TRUE(on_loop([&] { return loop_->send(frame).has_value(); }));
  on_loop([&] { loop_->hold_transmission(true); });
  EXPECT_FALSE(on_loop([&] { return loop_->send(frame).has_value(); }));
  EXPECT_FALSE(on_loop([&] { return loop_->send(frame).has_value(); }));
  EXPECT_EQ(on_loop([&] { return loop_->frames_held(); }), 2u);
  on_loop([&] { loop_->hold_transmission(false); });
  EXPECT_TRUE(on_loop([&] { return loop_->send(frame).has_value(); }));
  ASSERT_TRUE(eventually([&] { return spy_->frames(0x080).size() == 2; }));
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(spy_->frames(0x080).size(), 2u);
}

TEST_F(Loop, FramesNobodyHandlesAreCounted) {
  loop_->on_frame(0x181, [](const lb::can::CanFrame&) {});
  loop_->start();
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x181, {1})));
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x1FF, {1})));  // a node the bus does not know
  lb::can::CanFrame ext = lb::can::make_frame(0x1234567, {1});
  ext.extended = true;
  ASSERT_TRUE(spy_->send(ext));
  ASSERT_TRUE(eventually([&] { return on_loop([&] { return loop_->frames_unclaimed(); }) == 2; }));
}

TEST_F(Loop, RequestsBeyondTheQueueLimitAreRefusedAndCounted) {
  // The loop is busy (a task that waits for a gate) while requests keep coming: the first
  // kMaxPosted are taken, the rest refused at once (not run, counted), and once the loop is free
  // every taken one runs and new ones are taken again.
  std::promise<void> gate;
  auto opened = gate.get_future().share();
  loop_->start();
  std::promise<void> busy;
  loop_->post([opened, &busy] {
    busy.set_value();
    opened.wait();
  });
  busy.get_future().wait();  // the loop holds the gate's task now: the queue is empty
  std::atomic<std::size_t> ran{0};
  std::size_t taken = 0, refused = 0;
  for (std::size_t i = 0; i < BusLoop::kMaxPosted + 100; ++i) {
    if (loop_->try_post([&ran] { ++ran; })) {
      ++taken;
    } else {
      ++refused;
    }
  }
  EXPECT_EQ(taken, BusLoop::kMaxPosted);
  EXPECT_EQ(refused, 100u);
  EXPECT_EQ(loop_->posts_refused(), refused);
  gate.set_value();
  ASSERT_TRUE(eventually([&] { return ran == taken; }));
  EXPECT_TRUE(loop_->try_post([&ran] { ++ran; }));
  ASSERT_TRUE(eventually([&] { return ran == taken + 1; }));
  EXPECT_EQ(loop_->posts_refused(), refused);
}

// What a lane is to a bus loop: a descriptor it watches, read on the loop thread whenever there is
// something, until the callback has taken all of it (level-triggered).
TEST_F(Loop, AWatchedDescriptorIsReadOnTheLoopThreadUntilEmpty) {
  int pipe_fds[2];
  ASSERT_EQ(::pipe2(pipe_fds, O_NONBLOCK | O_CLOEXEC), 0);
  std::atomic<int> bytes{0}, off_loop{0};
  loop_->watch(pipe_fds[0], [&] {
    if (!loop_->on_loop_thread()) ++off_loop;
    char c;
    if (::read(pipe_fds[0], &c, 1) == 1) ++bytes;  // one byte per call: the rest brings it back
  });
  loop_->start();
  ASSERT_EQ(::write(pipe_fds[1], "abc", 3), 3);
  EXPECT_TRUE(eventually([&] { return bytes == 3; }, 20s)) << bytes << " of 3 bytes read";
  EXPECT_EQ(off_loop, 0);
  loop_->stop();
  ::close(pipe_fds[0]);
  ::close(pipe_fds[1]);
}

// Work posted on the loop thread (what a lane's set value does) runs in posting order, after the
// task that posted it; a task that posts itself again and again starves neither the timers nor
// other threads' posts.
TEST_F(Loop, WorkPostedOnTheLoopRunsInOrderAndARepostingTaskStarvesNothing) {
  std::vector<int> order;  // loop thread only
  std::atomic<bool> timer_ran{false}, stop_reposting{false}, reposting_done{false};
  std::atomic<int> reposts{0};
  std::function<void()> again = [&] {  // one in flight at a time: each posts at most the next
    ++reposts;
    if (stop_reposting) {
      reposting_done = true;
    } else {
      loop_->post(again);
    }
  };
  const auto t = loop_->create_timer([&] { timer_ran = true; });
  loop_->start();
  on_loop([&] {
    loop_->post([&] { order.push_back(1); });
    loop_->post([&] { order.push_back(2); });
    order.push_back(0);
  });
  EXPECT_EQ(on_loop([&] { return order; }), (std::vector<int>{0, 1, 2}));

  on_loop([&] {
    loop_->post(again);
    loop_->arm_timer(t, 1ms);
  });
  EXPECT_TRUE(eventually([&] { return timer_ran.load(); }, 20s)) << "the timer never ran beside the reposting task";
  std::atomic<bool> other_thread_ran{false};
  loop_->post([&] { other_thread_ran = true; });
  EXPECT_TRUE(eventually([&] { return other_thread_ran.load(); }, 20s)) << "another thread's post never ran";
  EXPECT_GT(reposts, 1);
  stop_reposting = true;
  // None left to run after this test's variables are gone.
  EXPECT_TRUE(eventually([&] { return reposting_done.load(); }, 20s));
}

// The bus's own time (what a heartbeat timeout is judged on): while a handler holds the loop up,
// the frames that come meanwhile are pending input, and the newest timestamp dispatched is the
// frame being handled, not the loop's clock; once they are read, nothing is pending and the
// newest timestamp is the last frame's.
TEST_F(Loop, TheBussTimeIsTheNewestFrameDispatchedAndQueuedFramesArePending) {
  std::promise<void> holding;
  std::promise<void> release;
  auto released = release.get_future().share();
  std::vector<std::int64_t> stamps;  // loop thread only
  std::atomic<bool> pending_while_held{false};
  std::atomic<std::int64_t> newest_while_held{0};
  loop_->on_frame(0x185, [&, released](const lb::can::CanFrame& f) {
    stamps.push_back(f.timestamp_ns);
    if (stamps.size() != 1) return;
    holding.set_value();
    released.wait();  // the other frames arrive meanwhile
    pending_while_held = loop_->input_pending();
    newest_while_held = loop_->last_frame_ns();
  });
  loop_->start();
  EXPECT_EQ(on_loop([&] { return loop_->last_frame_ns(); }), 0) << "a timestamp before any frame";
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x185, {0})));
  ASSERT_EQ(holding.get_future().wait_for(5s), std::future_status::ready);
  for (std::uint8_t i = 1; i <= 5; ++i) {
    std::this_thread::sleep_for(2ms);  // distinct stamps
    ASSERT_TRUE(spy_->send(lb::can::make_frame(0x185, {i})));
  }
  std::this_thread::sleep_for(100ms);  // stays: lets the frames reach the loop's socket while it is held
  release.set_value();
  ASSERT_TRUE(eventually([&] { return on_loop([&] { return stamps.size(); }) == 6; }));
  EXPECT_TRUE(pending_while_held) << "frames waited while the loop was held, and none was pending";
  const auto seen = on_loop([&] { return stamps; });
  EXPECT_EQ(newest_while_held, seen.front()) << "the bus's time ran ahead of the frames dispatched";
  EXPECT_EQ(on_loop([&] { return loop_->last_frame_ns(); }), *std::max_element(seen.begin(), seen.end()));
  EXPECT_GT(seen.back(), seen.front());
  EXPECT_FALSE(on_loop([&] { return loop_->input_pending(); })) << "pending input after every frame was read";
}

// A loop whose wake-ups were further apart than its stall guard (its process stopped) sends nothing
// but stops until it has read the frames that came meanwhile: a master frozen while a standby took
// the bus over must learn that before its next SYNC's RPDOs go out (docs/redundancy.md).
TEST_F(Loop, AStalledLoopReadsTheFramesOfMeanwhileBeforeItTransmitsAgain) {
  constexpr int kMeanwhile = 30;
  loop_->guard_stalls(100ms);
  int read = 0;                      // loop thread
  std::atomic<bool> blocked{false};  // the stall is over
  std::atomic<int> read_at_first_send{-1};
  loop_->on_frame(0x200, [&](const lb::can::CanFrame&) { ++read; });
  const auto tick = loop_->create_timer([&] {
    const bool sent = loop_->send(lb::can::make_frame(0x181, {0})).has_value();
    if (!blocked) return;
    if (sent && read_at_first_send < 0) read_at_first_send = read;
  });
  loop_->arm_timer(tick, 10ms, 10ms);
  loop_->start();
  ASSERT_TRUE(eventually([&] { return spy_->frames(0x181).size() >= 3; }));
  std::promise<void> holding;
  loop_->post([&] {
    holding.set_value();
    std::this_thread::sleep_for(400ms);  // stays: the stall being tested
    blocked = true;
  });
  ASSERT_EQ(holding.get_future().wait_for(5s), std::future_status::ready);
  for (int i = 0; i < kMeanwhile; ++i) ASSERT_TRUE(spy_->send(lb::can::make_frame(0x200, {1})));
  ASSERT_TRUE(eventually([&] { return read_at_first_send >= 0; }, 10s));
  EXPECT_EQ(read_at_first_send, kMeanwhile) << "it transmitted before it had read the frames of its stall";
  EXPECT_EQ(on_loop([&] { return loop_->stalls(); }), 1u);
}

// The stall over and its frames read, the loop transmits again though the bus stays busy: frames
// keep coming while its timer sends (a master booting its devices), and waiting for a moment with
// no input at all would hold its SYNC and heartbeat until a standby takes its silent bus over.
TEST_F(Loop, AfterAStallABusyBusDoesNotHoldTheTimersSendsOnceTheFramesOfMeanwhileAreRead) {
  loop_->guard_stalls(100ms);
  // Each frame takes the loop 1 ms, and they come faster: input is pending at every moment.
  loop_->on_frame(0x200, [](const lb::can::CanFrame&) {
    const auto until = std::chrono::steady_clock::now() + 1ms;
    while (std::chrono::steady_clock::now() < until) {
    }
  });
  const auto tick = loop_->create_timer([&] { (void)loop_->send(lb::can::make_frame(0x181, {0})); });
  loop_->arm_timer(tick, 10ms, 10ms);
  loop_->start();
  ASSERT_TRUE(eventually([&] { return spy_->frames(0x181).size() >= 3; }));
  std::atomic<bool> flooding{true};
  std::thread flood([&] {
    while (flooding) {
      (void)spy_->send(lb::can::make_frame(0x200, {1}));
      std::this_thread::sleep_for(200us);
    }
  });
  std::promise<void> holding;
  std::atomic<std::int64_t> stall_over_ns{0};
  loop_->post([&] {
    holding.set_value();
    std::this_thread::sleep_for(300ms);  // stays: the stall being tested
    stall_over_ns = lb::can::detail::realtime_ns();
  });
  ASSERT_EQ(holding.get_future().wait_for(5s), std::future_status::ready);
  const auto sent_after_stall = [&] {
    const auto over = stall_over_ns.load();
    if (over == 0) return std::size_t{0};
    const auto f = spy_->frames(0x181);
    return static_cast<std::size_t>(
        std::count_if(f.begin(), f.end(), [&](const lb::can::CanFrame& x) { return x.timestamp_ns > over; }));
  };
  const bool resumed = eventually([&] { return sent_after_stall() >= 10; }, 20s);
  flooding = false;
  flood.join();
  EXPECT_TRUE(resumed) << sent_after_stall() << " timer frames after the stall while the bus stayed busy";
  EXPECT_GE(on_loop([&] { return loop_->stalls(); }), 1u);
}

// The SYNC's timing as diagnostics and /metrics report it (SyncProducer::deviations): per SYNC,
// |interval from the SYNC before - period|. A loop held up for 6 periods sends its next SYNC that
// late: one interval of about 60 ms, 50 ms off a 10 ms period, beyond the 25 ms bound.
TEST_F(Loop, TheSyncsDeviationFromItsPeriodIsMeasuredAndAStallShows) {
  lb::canopen::SyncProducer sync(*loop_, 10ms);
  sync.start();
  loop_->start();
  const auto deviations = [&] { return on_loop([&] { return sync.deviations(); }); };
  ASSERT_TRUE(eventually([&] { return deviations().count() >= 5; })) << "no SYNCs measured";
  on_loop([] { std::this_thread::sleep_for(60ms); });  // the loop stalls
  ASSERT_TRUE(eventually([&] { return deviations().count() >= 12; }));
  const auto d = deviations();
  const auto& bounds = d.bounds();
  const auto at_25ms = static_cast<std::size_t>(std::find(bounds.begin(), bounds.end(), 0.025) - bounds.begin());
  ASSERT_LT(at_25ms, bounds.size()) << "25 ms is one of the documented bounds";
  EXPECT_GE(d.count() - d.cumulative(at_25ms), 1u) << "the stall is not among the deviations";
  EXPECT_GE(d.sum(), 0.045) << "the stall's 50 ms are not in the sum";
  // Every SYNC after the first has its interval measured: the bus carries one more than counted.
  EXPECT_TRUE(eventually([&] { return spy_->frames(0x080).size() >= d.count() + 1; }));
}
