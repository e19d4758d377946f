// Momentary commands counted on the bus (CiA 420-1: "not shorter than 100 ms"): a real bus loop
// with a SYNC producer and an RPDO transmitter over a virtual bus, wired as the gateways wire
// them, and a second bus member that sees the frames. What is checked is the frames: the bit is in
// a run of consecutive RPDOs whose first and clearing frames are at least 100 ms apart (taken where
// the transmitter hands them to the bus), and the answer reports exactly those frames.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/pdo_transmitter.hpp"
#include "canopen/sync_producer.hpp"
#include "gateways/node/momentary_commands.hpp"
#include "support/bus_spy.hpp"
#include "support/unit_loop_fixture.hpp"

using namespace std::chrono_literals;
using lb::canopen::BusLoop;
using lb::canopen::PdoTransmitter;
using lb::gateways::MomentaryCommands;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::uint32_t kRpdo1 = 0x205;
constexpr unsigned kBit = 3;  // a saw's manual_cut

class Momentary : public lb::test::LoopOnOwnBus {
 protected:
  Momentary() : LoopOnOwnBus("pulse") {}

  // The gateway's wiring: RPDO1 carries the control word (2 bytes), the commands watch its frames.
  void make(std::uint8_t transmission_type, bool with_sync = true) {
    commands_ = std::make_unique<MomentaryCommands>(
        *loop_, [this](unsigned bit, bool on) { word_ = on ? word_ | (1U << bit) : word_ & ~(1U << bit); },
        [this] { tx_->on_data(); });
    tx_ = std::make_unique<PdoTransmitter>(
        *loop_, PdoTransmitter::Settings{.can_id = kRpdo1, .transmission_type = transmission_type},
        PdoTransmitter::Hooks{.pack =
                                  [this](lb::can::CanFrame& f) {
                                    f.len = 2;
                                    f.data[0] = static_cast<std::uint8_t>(word_);
                                    f.data[1] = static_cast<std::uint8_t>(word_ >> 8);
                                  },
                              .may_send = [this] { return gate_.load(); },
                              .before_send = [this] { commands_->before_frame(); },
                              .sent =
                                  [this](const lb::can::CanFrame& f, Clock::time_point at) {
                                    {
                                      std::lock_guard lock(m_);
                                      sent_.push_back({(f.data[0] >> kBit & 1U) != 0, at});
                                    }
                                    // On the loop thread, so no SYNC after this frame sends one.
                                    if ((f.data[0] >> kBit & 1U) != 0 && pause_after_first_bit_) sync_paused_ = true;
                                    commands_->frame_sent(at);
                                  },
                              .not_sent =
                                  [this](PdoTransmitter::Refusal) { commands_->frame_not_sent("gate closed"); }});
    if (with_sync) {
      sync_ = std::make_unique<lb::canopen::SyncProducer>(*loop_, 20ms);
      sync_->on_sync([this] {
        if (!sync_paused_) tx_->on_sync();
      });
    }
    loop_->start();
    if (sync_) loop_->post([this] { sync_->start(); });
  }

  std::future<MomentaryCommands::Outcome> press(unsigned bit = kBit) {
    auto promise = std::make_shared<std::promise<MomentaryCommands::Outcome>>();
    auto future = promise->get_future();
    loop_->post([this, bit, promise] { commands_->press(bit, [promise](const auto& o) { promise->set_value(o); }); });
    return future;
  }
  static MomentaryCommands::Outcome wait(std::future<MomentaryCommands::Outcome>& f) {
    if (f.wait_for(5s) != std::future_status::ready) throw std::runtime_error("no answer within 5 s");
    return f.get();
  }

  struct Sent {
    bool bit;
    Clock::time_point at;
  };
  // The run of frames that carried the bit, and the frame that cleared it.
  struct Run {
    unsigned frames = 0;
    std::optional<Clock::duration> span;  // first carrying frame to the clearing frame
  };
  Run run() {
    std::lock_guard lock(m_);
    Run r;
    std::optional<Clock::time_point> first;
    for (const auto& s : sent_) {
      if (s.bit) {
        if (!first) first = s.at;
        ++r.frames;
      } else if (first) {
        r.span = s.at - *first;
        break;
      }
    }
    return r;
  }
  // The frames another bus member saw: the same run of bits.
  unsigned frames_seen_with_bit() {
    unsigned n = 0;
    for (const auto& f : spy_->frames(kRpdo1)) n += (f.data[0] >> kBit & 1U) != 0 ? 1 : 0;
    return n;
  }

  std::unique_ptr<MomentaryCommands> commands_;
  std::unique_ptr<PdoTransmitter> tx_;
  std::unique_ptr<lb::canopen::SyncProducer> sync_;
  std::atomic<bool> gate_{true};
  std::atomic<bool> sync_paused_{false};
  std::atomic<bool> pause_after_first_bit_{false};  // SYNCs stop right after the first frame with the bit
  std::uint16_t word_ = 0;                          // loop thread
  std::mutex m_;
  std::vector<Sent> sent_;
};

}  // namespace

TEST_F(Momentary, HeldUntilItsFramesSpanOneHundredMilliseconds) {
  make(1);
  auto f = press();
  const auto o = wait(f);
  ASSERT_TRUE(o.on_bus) << o.message;
  const auto r = run();
  ASSERT_TRUE(r.span) << "no frame cleared the bit";
  EXPECT_GE(*r.span, 100ms);
  EXPECT_GE(r.frames, 4u);  // at 20 ms SYNC: 5 or 6, fewer only when SYNCs come late
  EXPECT_EQ(o.frames, r.frames);
  EXPECT_GE(o.held, 100ms);
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(frames_seen_with_bit(), r.frames) << "another bus member saw another run";
  EXPECT_FALSE(commands_->held(kBit));
}

// A SYNC that does not come (a stalled loop, a late timer) makes the pulse longer, never shorter:
// the bit waits for a frame at least 100 ms after its first one.
TEST_F(Momentary, LateSyncsLengthenThePulse) {
  pause_after_first_bit_ = true;  // frames stop right after the first one that carries the bit
  make(1);
  auto f = press();
  // Waits on the event, not on a guess of when the loop gets to it (the machine may be loaded).
  for (auto until = Clock::now() + 5s; !sync_paused_ && Clock::now() < until;) std::this_thread::sleep_for(1ms);
  ASSERT_TRUE(sync_paused_) << "no frame carried the bit within 5 s";
  pause_after_first_bit_ = false;
  std::this_thread::sleep_for(250ms);
  EXPECT_EQ(f.wait_for(0ms), std::future_status::timeout) << "answered without a frame that clears the bit";
  sync_paused_ = false;
  const auto o = wait(f);
  ASSERT_TRUE(o.on_bus) << o.message;
  const auto r = run();
  ASSERT_TRUE(r.span);
  EXPECT_GE(*r.span, 250ms);
  EXPECT_EQ(o.frames, r.frames);
  EXPECT_LE(r.frames, 3u) << "the pause was not in the middle of the pulse";
}

TEST_F(Momentary, ADeviceThatTakesNoRpdoNeverGetsThePulseAndTheAnswerSaysSo) {
  gate_ = false;
  make(1);
  auto f = press();
  const auto o = wait(f);
  EXPECT_FALSE(o.on_bus);
  EXPECT_EQ(o.frames, 0u);
  EXPECT_NE(o.message.find("never reached the bus"), std::string::npos) << o.message;
  EXPECT_NE(o.message.find("gate closed"), std::string::npos) << o.message;
  gate_ = true;
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(frames_seen_with_bit(), 0u) << "a refused pulse reached the bus later";
}

TEST_F(Momentary, APulseCutShortIsAFailureWithWhatReachedTheBus) {
  make(1);
  auto f = press();
  // Two or three frames carry it, then the device stops taking RPDOs.
  while (run().frames < 2) std::this_thread::sleep_for(1ms);
  gate_ = false;
  const auto o = wait(f);
  EXPECT_FALSE(o.on_bus);
  EXPECT_GE(o.frames, 2u);
  EXPECT_LT(o.held, 100ms);
  EXPECT_NE(o.message.find("interrupted after"), std::string::npos) << o.message;
  gate_ = true;
  std::this_thread::sleep_for(100ms);
  const auto r = run();
  EXPECT_EQ(r.frames, o.frames) << "the bit came back after the refusal";
}

// An event-driven RPDO sends the bit at once and the release when the 100 ms are over.
TEST_F(Momentary, EventDrivenRpdoCarriesItInOneFrameAndReleasesItAfterTheHold) {
  make(255, false);
  auto f = press();
  const auto o = wait(f);
  ASSERT_TRUE(o.on_bus) << o.message;
  const auto r = run();
  EXPECT_EQ(r.frames, 1u);
  ASSERT_TRUE(r.span);
  EXPECT_GE(*r.span, 100ms);
  EXPECT_EQ(o.frames, 1u);
}

TEST_F(Momentary, PressingAgainWhileHeldExtendsTheHold) {
  make(1);
  auto first = press();
  while (run().frames < 3) std::this_thread::sleep_for(1ms);
  auto second = press();
  const auto a = wait(first);
  const auto b = wait(second);
  ASSERT_TRUE(a.on_bus && b.on_bus);
  EXPECT_GE(b.held, 100ms);
  EXPECT_GT(a.frames, b.frames);  // one run: the first press counts from earlier
  EXPECT_EQ(a.frames, run().frames);
}

// No frame within the patience (a PDO sent every n-th SYNC, a SYNC that stopped): not sent.
TEST_F(Momentary, APulseThatNoFrameCarriesIsAbandoned) {
  make(240);  // every 240th SYNC: 4.8 s, longer than the 2 s patience
  auto f = press();
  const auto o = wait(f);
  EXPECT_FALSE(o.on_bus);
  EXPECT_NE(o.message.find("no RPDO carrying the control word went out within 2000 ms"), std::string::npos)
      << o.message;
  EXPECT_FALSE(commands_->held(kBit));
}
