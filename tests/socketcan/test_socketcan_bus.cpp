// SocketCanBus on a real vcan (inside launch_scripts/vcan-run.sh): frames to and from can-utils,
// controller states from error frames, the link going down and coming back (also deleted and
// re-created) under a running BusLoop, a full transmit queue, and recording and replay checked
// against the real candump -l. The parts that need no kernel CAN are in tests/unit/test_can_log.cpp.
#include <gtest/gtest.h>
#include <linux/can/error.h>
#include <poll.h>

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <thread>

#include "can/bus.hpp"
#include "can/log_bus.hpp"
#include "can/recording_bus.hpp"
#include "can/socketcan_bus.hpp"
#include "canopen/bus_loop.hpp"
#include "support/drain_bus.hpp"
#include "vcan_tools.hpp"

namespace lb::can {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using test::cansend;
using test::drain;
using test::sh;

std::unique_ptr<Bus> must_open(const std::string& ifname) {
  auto bus = SocketCanBus::open(ifname);
  if (!bus) throw std::runtime_error(bus.error().message);
  return std::move(*bus);
}

bool same_frame(const CanFrame& a, const CanFrame& b) {
  return a.id == b.id && a.extended == b.extended && a.rtr == b.rtr && a.error == b.error && a.len == b.len &&
         std::equal(a.data.begin(), a.data.begin() + a.len, b.data.begin());
}

// A vcan of the test's own, so taking it down or deleting it never disturbs vcan0.
class OwnVcan {
 public:
  explicit OwnVcan(std::string name) : name_(std::move(name)) {
    sh("ip link del " + name_ + " 2>/dev/null");
    EXPECT_EQ(sh("ip link add dev " + name_ + " type vcan && ip link set " + name_ + " up"), 0);
  }
  ~OwnVcan() { sh("ip link del " + name_ + " 2>/dev/null"); }
  const std::string& name() const { return name_; }

 private:
  std::string name_;
};

class SocketCan : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(sh("ip link show vcan0 >/dev/null"), 0) << "no vcan0: run through launch_scripts/vcan-run.sh";
  }
};

TEST_F(SocketCan, ReceivesExactlyWhatCansendSends) {
  auto bus = must_open("vcan0");
  const auto before = std::chrono::system_clock::now();
  ASSERT_TRUE(cansend("vcan0", "185#0200785634120000"));
  ASSERT_TRUE(cansend("vcan0", "12345678#DEAD"));
  ASSERT_TRUE(cansend("vcan0", "705#R"));
  const auto frames = drain(*bus, 3);
  ASSERT_EQ(frames.size(), 3u);
  EXPECT_TRUE(same_frame(frames[0], make_frame(0x185, {0x02, 0x00, 0x78, 0x56, 0x34, 0x12, 0x00, 0x00})));
  EXPECT_TRUE(frames[1].extended);
  EXPECT_EQ(frames[1].id, 0x12345678u);
  EXPECT_EQ(frames[1].len, 2);
  EXPECT_TRUE(frames[2].rtr);
  EXPECT_EQ(frames[2].id, 0x705u);
  const auto ts = std::chrono::system_clock::time_point(std::chrono::nanoseconds(frames[0].timestamp_ns));
  EXPECT_GE(ts, before - 1s) << "kernel receive timestamps";
  EXPECT_EQ(bus->stats().frames_in, 3u);
  EXPECT_EQ(bus->stats().state, BusState::error_active);
}

TEST_F(SocketCan, SentFramesAreWhatCandumpRecords) {
  auto bus = must_open("vcan0");
  test::Candump candump("vcan0");
  CanFrame eff = make_frame(0x1ABCDEF, {0x11, 0x22});
  eff.extended = true;
  CanFrame rtr;
  rtr.id = 0x701;
  rtr.rtr = true;
  ASSERT_TRUE(bus->send(make_frame(0x205, {0x05, 0x00, 0x88, 0x13, 0x88, 0x13, 0x00, 0x00})));
  ASSERT_TRUE(bus->send(eff));
  ASSERT_TRUE(bus->send(rtr));
  ASSERT_TRUE(bus->send(make_frame(0x080, {})));
  std::this_thread::sleep_for(300ms);
  const std::string text = candump.text();
  EXPECT_NE(text.find(" vcan0 205#0500881388130000\n"), std::string::npos) << text;
  EXPECT_NE(text.find(" vcan0 01ABCDEF#1122\n"), std::string::npos) << text;
  EXPECT_NE(text.find(" vcan0 701#R\n"), std::string::npos) << text;
  EXPECT_NE(text.find(" vcan0 080#\n"), std::string::npos) << text;
  EXPECT_EQ(bus->stats().frames_out, 4u);
}

TEST_F(SocketCan, ErrorFramesDriveTheControllerState) {
  auto bus = must_open("vcan0");
  const auto state_after = [&](const std::string& frame) {
    EXPECT_TRUE(cansend("vcan0", frame)) << frame;
    const auto got = drain(*bus, 1);
    EXPECT_EQ(got.size(), 1u) << frame;
    if (!got.empty()) {
      EXPECT_TRUE(got[0].error) << frame;
    }
    return bus->stats().state;
  };
  // Injected by an independent peer exactly as a controller driver reports them (CAN_ERR_FLAG set:
  // 8 hex digits of id). CRTL|CNT, TX warning, TEC 96 / REC 3:
  EXPECT_EQ(state_after("20000204#0008000000006003"), BusState::error_warning);
  EXPECT_EQ(bus->stats().tx_error_counter, 96);
  EXPECT_EQ(bus->stats().rx_error_counter, 3);
  EXPECT_EQ(state_after("20000204#0020000000008003"), BusState::error_passive);  // TX passive, TEC 128
  EXPECT_EQ(state_after("20000040#0000000000000000"), BusState::bus_off);
  EXPECT_EQ(bus->stats().bus_offs, 1u);
  EXPECT_EQ(state_after("20000100#0000000000000000"), BusState::error_active);  // restarted
  EXPECT_EQ(state_after("20000004#0001000000000000"), BusState::error_active);  // RX overflow
  EXPECT_EQ(bus->stats().rx_overflows, 1u);
  EXPECT_EQ(bus->stats().error_frames, 5u);
  EXPECT_EQ(bus->stats().frames_in, 0u);
}

// Reads the bus's stats on the loop thread (the bus belongs to it).
BusStats loop_stats(canopen::BusLoop& loop) {
  std::promise<BusStats> p;
  auto f = p.get_future();
  loop.post([&] { p.set_value(loop.stats()); });
  return f.get();
}

template <class Pred>
bool wait_for(Pred pred, std::chrono::milliseconds timeout = 5000ms) {
  const auto deadline = Clock::now() + timeout;
  while (!pred()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(20ms);
  }
  return true;
}

// A BusLoop as the bridge runs it: SYNC-like periodic send, frames counted. fd() must stay valid
// across re-opens, since the loop registered it once.
class LoopOnLink {
 public:
  explicit LoopOnLink(const std::string& ifname) : loop_(must_open(ifname)) {
    loop_.on_frame(0x123, [this](const CanFrame&) { ++received_; });
    const auto t = loop_.create_timer([this] {
      if (loop_.send(make_frame(0x080, {}))) ++sent_ok_;
    });
    loop_.arm_timer(t, 20ms, 20ms);
    loop_.start();
  }
  ~LoopOnLink() { loop_.stop(); }
  canopen::BusLoop& loop() { return loop_; }
  std::atomic<int> received_{0};
  std::atomic<int> sent_ok_{0};

 private:
  canopen::BusLoop loop_;
};

void expect_link_cycle(const std::string& ifname, const std::string& down_cmd, const std::string& up_cmd,
                       std::uint64_t reopens_before) {
  LoopOnLink l(ifname);
  ASSERT_TRUE(wait_for([&] { return l.sent_ok_ > 3; }));
  ASSERT_TRUE(cansend(ifname, "123#01"));
  ASSERT_TRUE(wait_for([&] { return l.received_ == 1; }));

  ASSERT_EQ(sh(down_cmd), 0) << down_cmd;
  ASSERT_TRUE(wait_for([&] { return loop_stats(l.loop()).state == BusState::down; })) << "link down not seen";
  const int sent_while_down = l.sent_ok_;
  std::this_thread::sleep_for(300ms);
  EXPECT_LE(l.sent_ok_ - sent_while_down, 1) << "nothing can be sent on a link that is down";
  EXPECT_GT(loop_stats(l.loop()).tx_dropped, 0u);

  ASSERT_EQ(sh(up_cmd), 0) << up_cmd;
  ASSERT_TRUE(wait_for([&] { return loop_stats(l.loop()).reopens == reopens_before + 1; })) << "not re-opened";
  EXPECT_EQ(loop_stats(l.loop()).state, BusState::error_active);
  const int sent_after = l.sent_ok_;
  ASSERT_TRUE(wait_for([&] { return l.sent_ok_ > sent_after + 3; })) << "the periodic send did not resume";
  ASSERT_TRUE(cansend(ifname, "123#02"));
  ASSERT_TRUE(wait_for([&] { return l.received_ == 2; })) << "no reception after the re-open";
}

TEST_F(SocketCan, ALinkTakenDownAndUpIsReopenedUnderARunningLoop) {
  OwnVcan vcan("lbupdown0");
  expect_link_cycle(vcan.name(), "ip link set lbupdown0 down", "ip link set lbupdown0 up", 0);
}

TEST_F(SocketCan, ADeletedAndRecreatedInterfaceIsReopened) {
  OwnVcan vcan("lbdel0");
  expect_link_cycle(vcan.name(), "ip link del lbdel0", "ip link add dev lbdel0 type vcan && ip link set lbdel0 up", 0);
}

TEST_F(SocketCan, AnInterfaceThatIsDownAtStartIsWaitedFor) {
  OwnVcan vcan("lblate0");
  ASSERT_EQ(sh("ip link set lblate0 down"), 0);
  auto bus = must_open("lblate0");
  EXPECT_EQ(bus->stats().state, BusState::down);
  EXPECT_FALSE(bus->send(make_frame(0x080, {})));
  ASSERT_EQ(sh("ip link set lblate0 up"), 0);
  const auto deadline = Clock::now() + 3s;
  while (bus->stats().state == BusState::down && Clock::now() < deadline) {
    pollfd p{bus->fd(), POLLIN, 0};
    ::poll(&p, 1, 50);
    ASSERT_TRUE(bus->receive());
  }
  EXPECT_EQ(bus->stats().state, BusState::error_active);
  EXPECT_TRUE(bus->send(make_frame(0x080, {})));
}

TEST_F(SocketCan, MissingOrNonCanInterfacesFailAtOpen) {
  auto missing = SocketCanBus::open("nosuchcan0");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().message.find("no network interface"), std::string::npos) << missing.error().message;
  auto lo = SocketCanBus::open("lo");
  ASSERT_FALSE(lo);
  EXPECT_NE(lo.error().message.find("not a CAN interface"), std::string::npos) << lo.error().message;
}

TEST_F(SocketCan, AFullTransmitQueueIsCountedAndNeverWaitedOn) {
  // A token bucket holding a handful of frames: past it the qdisc drops and send() gets ENOBUFS,
  // as a real controller's full queue does.
  OwnVcan vcan("lbfull0");
  ASSERT_EQ(sh("tc qdisc add dev lbfull0 root tbf rate 8kbit burst 64 limit 64"), 0) << "needs sch_tbf";
  auto bus = must_open("lbfull0");
  int ok = 0;
  int full = 0;
  const auto t0 = Clock::now();
  for (int i = 0; i < 2000; ++i) {
    auto r = bus->send(make_frame(0x181, {static_cast<std::uint8_t>(i)}));
    if (r) {
      ++ok;
    } else {
      ++full;
      EXPECT_NE(r.error().message.find("transmit queue full"), std::string::npos) << r.error().message;
    }
  }
  const auto elapsed = Clock::now() - t0;
  EXPECT_LT(elapsed, 2s) << "send() must never wait for room";
  EXPECT_GT(full, 1000);
  const BusStats s = bus->stats();
  EXPECT_EQ(s.tx_queue_full, static_cast<std::uint64_t>(full));
  EXPECT_EQ(s.tx_dropped, static_cast<std::uint64_t>(full));
  EXPECT_EQ(s.frames_out, static_cast<std::uint64_t>(ok));
  EXPECT_EQ(s.state, BusState::error_active) << "congestion is not a controller fault";
}

TEST_F(SocketCan, ARecordingHoldsWhatCandumpRecords) {
  test::Candump candump("vcan0");
  const std::string path = ::testing::TempDir() + "/recording-" + std::to_string(::getpid()) + ".log";
  ::unlink(path.c_str());
  auto rec = RecordingBus::open(must_open("vcan0"), path);
  ASSERT_TRUE(rec) << rec.error().message;
  for (const char* f : {"185#0200785634120000", "12345678#DEAD", "705#R", "20000040#0000000000000000", "080#"}) {
    ASSERT_TRUE(cansend("vcan0", f));
  }
  ASSERT_EQ(drain(**rec, 5).size(), 5u);
  ASSERT_TRUE((*rec)->send(make_frame(0x205, {0x01, 0x02})));
  std::this_thread::sleep_for(300ms);

  const auto dumped = candump.records();
  auto ours = LogBus::open(path + "?pace=fast");
  ASSERT_TRUE(ours) << ours.error().message;
  const auto replayed = drain(**ours, 6);
  ASSERT_EQ(dumped.size(), 6u) << candump.text();
  ASSERT_EQ(replayed.size(), 6u);
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_TRUE(same_frame(dumped[i].frame, replayed[i])) << "frame " << i;
    EXPECT_LT(std::abs(dumped[i].frame.timestamp_ns - replayed[i].timestamp_ns), 500'000'000) << "frame " << i;
  }
}

TEST_F(SocketCan, ACandumpRecordingReplaysAtItsPace) {
  test::Candump candump("vcan0");
  const std::vector<std::string> sent = {
      "705#05", "185#0200785634120000", "285#F401000010270000", "20000040#0000000000000000", "1ABCDEF0#01", "701#R"};
  for (const auto& f : sent) {
    ASSERT_TRUE(cansend("vcan0", f));
    std::this_thread::sleep_for(100ms);
  }
  const auto dumped = candump.records();
  ASSERT_EQ(dumped.size(), sent.size()) << candump.text();
  const double recorded_s = static_cast<double>(dumped.back().frame.timestamp_ns - dumped.front().frame.timestamp_ns) /
                            1e9;

  auto replay = open_bus("log:" + candump.path());
  ASSERT_TRUE(replay) << replay.error().message;
  const auto t0 = Clock::now();
  const auto frames = drain(**replay, sent.size(), 10s);
  const double replay_s = std::chrono::duration<double>(Clock::now() - t0).count();
  ASSERT_EQ(frames.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i) {
    EXPECT_TRUE(same_frame(frames[i], dumped[i].frame)) << sent[i];
    EXPECT_EQ(frames[i].timestamp_ns, dumped[i].frame.timestamp_ns) << sent[i];
  }
  EXPECT_GE(replay_s, recorded_s - 0.01);
  EXPECT_LT(replay_s, recorded_s + 1.0);
  EXPECT_EQ((*replay)->stats().bus_offs, 1u);
  EXPECT_FALSE((*replay)->send(make_frame(0x080, {}))) << "a replay is receive-only";
}

}  // namespace
}  // namespace lb::can
