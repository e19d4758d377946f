// When PDOs go on the bus (CiA 301 transmission types), on a real bus loop over a virtual bus,
// watched by a second bus member.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <future>
#include <thread>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/pdo_transmitter.hpp"
#include "support/bus_spy.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
using lb::canopen::BusLoop;
using lb::canopen::PdoTransmitter;

namespace {

class Transmitter : public lb::test::LoopOnOwnBus {
 protected:
  Transmitter() : LoopOnOwnBus("tx") {}

  // Creates the transmitter on the loop thread's side of the start, then starts the loop.
  // quiet: how long from now the transmitter sends nothing (PdoTransmitter::quiet_until).
  void make(PdoTransmitter::Settings s, std::chrono::milliseconds quiet = 0ms) {
    s.can_id = 0x181;
    tx_ = std::make_unique<PdoTransmitter>(
        *loop_, s,
        PdoTransmitter::Hooks{.pack =
                                  [this](lb::can::CanFrame& f) {
                                    f.len = 2;
                                    f.data[0] = value_.load();
                                    f.data[1] = 0xAB;
                                  },
                              .may_send = [this] { return gate_.load(); },
                              .sent = [this](const lb::can::CanFrame&, auto) { ++sent_; },
                              .not_sent = [this](PdoTransmitter::Refusal) { ++refused_; }});
    quiet_from_ = std::chrono::system_clock::now();  // before the quiet time's start: a bound for the bus's stamps
    if (quiet > 0ms) tx_->quiet_until(std::chrono::steady_clock::now() + quiet);
    loop_->start();
  }
  // Runs on the loop thread and waits for it.
  void on_loop(std::function<void()> f) {
    std::promise<void> done;
    loop_->post([&] {
      f();
      done.set_value();
    });
    done.get_future().wait();
  }
  // The frames on the bus: after `settle` (for a test that lets timers run), every frame the
  // transmitter reported sent by then, waited for as it reaches the spy (generously: a loaded
  // machine delays delivery, never the count).
  std::vector<lb::can::CanFrame> sent_frames(std::chrono::milliseconds settle = 0ms) {
    std::this_thread::sleep_for(settle);
    const auto expected = static_cast<std::size_t>(sent_.load());
    const auto deadline = std::chrono::steady_clock::now() + 10s;
    auto frames = spy_->frames(0x181);
    while (frames.size() < expected && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(2ms);
      frames = spy_->frames(0x181);
    }
    return frames;
  }

  // The earliest a frame may carry (CLOCK_REALTIME, as the bus stamps frames) after a quiet time.
  std::int64_t quiet_over_ns(std::chrono::milliseconds quiet) const {
    return std::chrono::duration_cast<std::chrono::nanoseconds>((quiet_from_ + quiet).time_since_epoch()).count();
  }

  std::unique_ptr<PdoTransmitter> tx_;
  std::chrono::system_clock::time_point quiet_from_;
  std::atomic<std::uint8_t> value_{1};
  std::atomic<bool> gate_{true};
  std::atomic<int> sent_{0};
  std::atomic<int> refused_{0};
};

}  // namespace

TEST_F(Transmitter, SynchronousEveryNthSync) {
  make({.transmission_type = 3});
  for (int i = 0; i < 9; ++i) on_loop([this] { tx_->on_sync(); });
  EXPECT_EQ(sent_frames().size(), 3u);
  EXPECT_EQ(sent_, 3);
}

TEST_F(Transmitter, SynchronousAcyclicOnlyWhenChanged) {
  make({.transmission_type = 0});
  on_loop([this] { tx_->on_sync(); });  // first: nothing sent yet counts as changed
  on_loop([this] { tx_->on_sync(); });
  on_loop([this] { tx_->on_sync(); });
  value_ = 2;
  on_loop([this] { tx_->on_data(); });  // no SYNC: acyclic waits for one
  EXPECT_EQ(sent_frames().size(), 1u);
  on_loop([this] { tx_->on_sync(); });
  const auto frames = sent_frames();
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[1].data[0], 2);
}

TEST_F(Transmitter, EventDrivenRespectsInhibitTime) {
  make({.transmission_type = 255, .inhibit = 50ms});
  for (std::uint8_t v = 10; v < 15; ++v) {
    value_ = v;
    on_loop([this] { tx_->on_data(); });  // five changes in quick succession
  }
  on_loop([this] { tx_->on_sync(); });  // SYNC means nothing to an event-driven PDO
  const auto frames = sent_frames(200ms);
  ASSERT_EQ(frames.size(), 2u) << "the first at once, the latest value when the inhibit time is over";
  EXPECT_EQ(frames[0].data[0], 10);
  EXPECT_EQ(frames[1].data[0], 14);
  // Reception times at the spy carry delivery jitter; without the inhibit the gap would be ~0.
  EXPECT_GE(frames[1].timestamp_ns - frames[0].timestamp_ns, 25'000'000);
  on_loop([this] { tx_->on_data(); });  // unchanged: nothing
  EXPECT_EQ(sent_frames().size(), 2u);
}

// Waited for, not counted in a window (a loaded machine delays a timer, it never hastens one): the
// sixth frame is the event timer's fifth resend, so it cannot come before five event times.
TEST_F(Transmitter, EventTimerResendsUnchangedData) {
  make({.transmission_type = 254, .event_timer = 60ms});
  const auto asked = std::chrono::steady_clock::now();
  on_loop([this] { tx_->on_data(); });
  const auto frames = spy_->wait_count(0x181, 6, 10s);
  const auto seen_after = std::chrono::steady_clock::now() - asked;
  ASSERT_GE(frames.size(), 6u) << "unchanged data not resent by the event timer";
  for (const auto& f : frames) EXPECT_EQ(f.data[0], 1);
  EXPECT_GE(seen_after, 5 * 60ms) << "resent faster than the event timer";
}

// Remote-only types (252/253) never send on their own; a closed gate (the device not started)
// sends nothing on any trigger and says so; once it opens, the next trigger sends. "Nothing sent"
// is read from the transmitter's own hooks (they run on the loop thread before on_loop returns)
// and from the bus without a settling time: the bus keeps its order, so a frame sent before the
// one that proves the gate open would have reached the spy before it.
TEST_F(Transmitter, RemoteOnlyTypesAndAClosedGateSendNothing) {
  make({.transmission_type = 253});
  on_loop([this] {
    for (int i = 0; i < 3; ++i) tx_->on_sync();
    tx_->on_data();
  });
  EXPECT_EQ(sent_, 0) << "a remote-only PDO went out on its own";

  gate_ = false;
  value_ = 1;
  on_loop([this] { tx_->reconfigure({.can_id = 0x181, .transmission_type = 1}); });  // every SYNC
  on_loop([this] {
    for (int i = 0; i < 3; ++i) tx_->on_sync();
  });
  EXPECT_EQ(sent_, 0) << "sent through a closed gate";
  EXPECT_EQ(refused_, 3) << "each SYNC found the gate closed";

  gate_ = true;
  value_ = 2;
  on_loop([this] { tx_->on_sync(); });
  EXPECT_EQ(sent_, 1) << "the open gate let nothing out";
  EXPECT_EQ(refused_, 3);
  std::vector<lb::can::CanFrame> frames;
  for (const auto until = std::chrono::steady_clock::now() + 5s;
       (frames = spy_->frames(0x181)).empty() && std::chrono::steady_clock::now() < until;) {
    std::this_thread::sleep_for(5ms);
  }
  ASSERT_EQ(frames.size(), 1u) << "before the gate opened, frames reached the bus";
  EXPECT_EQ(frames[0].data[0], 2) << "the frame on the bus is not the one sent after the gate opened";
}

TEST_F(Transmitter, ClosedGateHoldsBackAndResendCatchesUp) {
  gate_ = false;
  make({.transmission_type = 255});
  on_loop([this] { tx_->on_data(); });
  EXPECT_TRUE(sent_frames().empty());
  gate_ = true;
  on_loop([this] { tx_->on_data(); });  // data unchanged since the refused attempt, still unsent
  EXPECT_EQ(sent_frames().size(), 1u);
  on_loop([this] { tx_->resend(); });  // a restarted device gets the image again
  EXPECT_EQ(sent_frames().size(), 2u);
}

TEST_F(Transmitter, TwentyNineBitIdentifier) {
  make({.extended = true, .transmission_type = 1});
  on_loop([this] { tx_->on_sync(); });
  const auto frames = sent_frames();
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_TRUE(frames[0].extended);
}

// CiA 301: the event timer of an event-driven PDO restarts with every transmission. A trigger that
// could not send (device not started, bus refused) must not stop it: the PDO goes out again once
// it may, without waiting for its data to change.
TEST_F(Transmitter, EventTimerKeepsRunningAfterARefusedSend) {
  gate_ = false;
  make({.transmission_type = 254, .event_timer = 60ms});
  on_loop([this] { tx_->on_data(); });
  EXPECT_TRUE(sent_frames().empty());
  EXPECT_GE(refused_.load(), 1);
  gate_ = true;  // no data change, no resend: only the event timer can send it now
  const auto frames = sent_frames(400ms);
  EXPECT_GE(frames.size(), 3u) << "the event timer stopped after the refused send";
}

// A resend (the device restarted, came online again) is a frame of this PDO like any other: it
// waits for the inhibit time after the previous one.
TEST_F(Transmitter, ResendRespectsTheInhibitTime) {
  make({.transmission_type = 255, .inhibit = 200ms});
  on_loop([this] { tx_->on_data(); });
  on_loop([this] { tx_->resend(); });  // at once: the inhibit time is not over
  EXPECT_EQ(sent_frames(50ms).size(), 1u) << "the resend did not wait for the inhibit time";
  const auto frames = sent_frames(400ms);
  ASSERT_EQ(frames.size(), 2u) << "the resend is sent once the inhibit time is over";
  // Reception times at the spy carry delivery jitter; without the inhibit the gap would be ~0.
  EXPECT_GE(frames[1].timestamp_ns - frames[0].timestamp_ns, 150'000'000);
}

TEST_F(Transmitter, RefusalsAreReportedWithTheirCause) {
  gate_ = false;
  make({.transmission_type = 1});
  on_loop([this] { tx_->on_sync(); });
  EXPECT_EQ(refused_.load(), 1);
  EXPECT_EQ(sent_.load(), 0);
  gate_ = true;
  on_loop([this] { tx_->on_sync(); });
  EXPECT_EQ(sent_.load(), 1);
  EXPECT_EQ(refused_.load(), 1);
}

// A new bus side holds its RPDOs back at first (a press its predecessor began keeps its 100 ms):
// an event-driven PDO due then is not refused but goes out once the quiet time is over.
TEST_F(Transmitter, AQuietTimeHoldsAnEventDrivenPdoBackAndThenSendsIt) {
  make({.transmission_type = 255}, 1000ms);
  on_loop([this] { tx_->on_data(); });
  value_ = 7;
  on_loop([this] { tx_->on_data(); });
  on_loop([this] { tx_->resend(); });
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (sent_.load() == 0 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(2ms);
  const auto frames = sent_frames();
  ASSERT_EQ(frames.size(), 1u) << "held back, then sent once with the latest data";
  EXPECT_EQ(frames[0].data[0], 7);
  EXPECT_GE(frames[0].timestamp_ns, quiet_over_ns(1000ms)) << "sent inside the quiet time";
  EXPECT_EQ(refused_.load(), 0) << "a trigger inside the quiet time is held back, not refused";
}

// A synchronous PDO is never sent between SYNCs (a device takes it in its SYNC window): the
// first SYNC after the quiet time sends it, though it is not the n-th; then every n-th again.
TEST_F(Transmitter, AQuietTimeHoldsASynchronousPdoBackUntilTheFirstSyncAfterIt) {
  make({.transmission_type = 3}, 1000ms);
  for (int i = 0; i < 4; ++i) on_loop([this] { tx_->on_sync(); });
  EXPECT_EQ(sent_.load(), 0) << "sent inside the quiet time";
  EXPECT_EQ(refused_.load(), 0) << "a SYNC inside the quiet time holds the PDO back, it does not refuse it";
  std::this_thread::sleep_for(1100ms);  // past the quiet time: no SYNC, so nothing may go out
  EXPECT_EQ(sent_.load(), 0) << "a synchronous PDO went out without a SYNC";
  on_loop([this] { tx_->on_sync(); });  // the first after it: the 5th, not a 3rd
  auto frames = sent_frames();
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_GE(frames[0].timestamp_ns, quiet_over_ns(1000ms));
  for (int i = 0; i < 3; ++i) on_loop([this] { tx_->on_sync(); });
  EXPECT_EQ(sent_frames().size(), 2u) << "then every 3rd SYNC again";
}
