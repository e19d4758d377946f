// The simulator's heartbeat consumer (1016h), as CiA 301 defines it: one entry, sub 1 = node-ID
// (bits 16..23) and consumer time in ms (bits 0..15). Active from the first heartbeat of that
// node after it was written; that heartbeat missing for the consumer time: EMCY 8130h (heartbeat
// error) and, by 1029h sub 1's default 0, operational -> pre-operational; its return: EMCY 0000h
// (error reset). Reset communication restores 0. A simulated saw (node 5) and this test, which
// plays the master with raw frames (NMT, SDO, its heartbeat on 701h), on one virtual bus.
// Expected frames by hand from CiA 301 (cia301-essentials.md).
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <string>
#include <thread>

#include "canopen/bus_loop.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "sim/device_simulator.hpp"
#include "support/bus_spy.hpp"
#include "support/eventually.hpp"

namespace {

using namespace std::chrono_literals;
using lb::can::make_frame;

class SimHeartbeatConsumer : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string bus = "virtual:hc" + std::to_string(::getpid()) + "-" + info->name();
    bus.resize(std::min<std::size_t>(bus.size(), 90));
    auto config = lb::profiles::parse_line_config(
        "line: consumer\nbuses:\n  - {name: b, interface: '" + bus +
            "'}\ndevices:\n  - {name: saw, bus: b, node_id: 5, profile: cia420-4, version: '3.1',\n"
            "     simulation: {heartbeat_period_ms: 50}}\n",
        "consumer.yaml", registry_);
    ASSERT_TRUE(config) << config.error().message;
    config_ = std::move(*config);
    spy_ = std::make_unique<lb::test::BusSpy>(bus);  // first: the hub lives here
    loop_ = std::make_unique<lb::canopen::BusLoop>(lb::can::open_bus(bus).value());
    device_ = lb::sim::make_simulator(*loop_, config_.devices.at(0));
    device_->start();
    loop_->start();
  }
  void TearDown() override {
    if (loop_) loop_->stop();
  }

  bool last_heartbeat_is(std::uint8_t state) {
    return lb::test::eventually(10s, [&] {
      const auto hb = spy_->frames(0x705);
      return !hb.empty() && hb.back().len == 1 && hb.back().data[0] == state;
    });
  }
  std::size_t emcys_with(std::uint16_t code) {
    std::size_t n = 0;
    for (const auto& f : spy_->frames(0x085)) {
      if (f.len == 8 && f.data[0] == (code & 0xFF) && f.data[1] == (code >> 8)) ++n;
    }
    return n;
  }
  // An expedited SDO transfer from this test; the device's answer (585h) for it.
  lb::can::CanFrame sdo(std::initializer_list<std::uint8_t> request) {
    const auto before = spy_->frames(0x585).size();
    EXPECT_TRUE(spy_->send(make_frame(0x605, request)));
    EXPECT_TRUE(lb::test::eventually(10s, [&] { return spy_->frames(0x585).size() > before; }));
    const auto answers = spy_->frames(0x585);
    return answers.size() > before ? answers[before] : lb::can::CanFrame{};
  }
  void beat_for(std::chrono::milliseconds total) {
    for (auto t = 0ms; t < total; t += 50ms) {
      ASSERT_TRUE(spy_->send(make_frame(0x701, {0x05})));
      std::this_thread::sleep_for(50ms);  // stays: the master's heartbeat period
    }
  }

  lb::profiles::ProfileRegistry registry_ = lb::profiles::ProfileRegistry::builtin();
  lb::profiles::LineConfig config_;
  std::unique_ptr<lb::test::BusSpy> spy_;
  std::unique_ptr<lb::canopen::BusLoop> loop_;
  std::unique_ptr<lb::sim::DeviceSimulator> device_;
};

TEST_F(SimHeartbeatConsumer, AMissingMasterHeartbeatIsAHeartbeatEventAndItsReturnResetsTheError) {
  ASSERT_TRUE(last_heartbeat_is(0x7F));
  // 1016h sub 0: one entry; sub 1: unused at power-on.
  auto a = sdo({0x40, 0x16, 0x10, 0x00, 0, 0, 0, 0});
  EXPECT_EQ(a.data[0], 0x4F);  // expedited upload, 1 byte
  EXPECT_EQ(a.data[4], 1);
  a = sdo({0x40, 0x16, 0x10, 0x01, 0, 0, 0, 0});
  EXPECT_EQ(a.data[0], 0x43);
  EXPECT_EQ(a.data[4] | a.data[5] | a.data[6] | a.data[7], 0);
  // Node 1, 200 ms; read back.
  a = sdo({0x23, 0x16, 0x10, 0x01, 0xC8, 0x00, 0x01, 0x00});
  EXPECT_EQ(a.data[0], 0x60);
  a = sdo({0x40, 0x16, 0x10, 0x01, 0, 0, 0, 0});
  EXPECT_EQ(a.data[0], 0x43);
  EXPECT_EQ(a.data[4], 0xC8);
  EXPECT_EQ(a.data[5], 0x00);
  EXPECT_EQ(a.data[6], 0x01);
  EXPECT_EQ(a.data[7], 0x00);
  ASSERT_TRUE(spy_->send(make_frame(0x000, {0x01, 0x05})));  // start node 5
  ASSERT_TRUE(last_heartbeat_is(0x05));
  // Not active before the first heartbeat of node 1: no event however long it is silent.
  std::this_thread::sleep_for(500ms);  // stays: an event would come within it
  EXPECT_EQ(emcys_with(0x8130), 0u);
  // The master beats every 50 ms for a second: no event.
  beat_for(1000ms);
  EXPECT_EQ(emcys_with(0x8130), 0u);
  ASSERT_TRUE(last_heartbeat_is(0x05));
  // Silent: the event (EMCY 8130h, error register bit 0 generic and bit 4 communication), and
  // the device leaves operational for pre-operational.
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return emcys_with(0x8130) == 1; }));
  const auto emcy = spy_->frames(0x085).back();
  EXPECT_EQ(emcy.data[2], 0x11);
  ASSERT_TRUE(last_heartbeat_is(0x7F));
  // It beats again: error reset (EMCY 0000h); the device stays pre-operational.
  beat_for(200ms);
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return emcys_with(0x0000) >= 1; }));
  EXPECT_EQ(emcys_with(0x8130), 1u);
  EXPECT_EQ(spy_->frames(0x705).back().data[0], 0x7F);
}

TEST_F(SimHeartbeatConsumer, ResetCommunicationRestoresNoEntry) {
  auto a = sdo({0x23, 0x16, 0x10, 0x01, 0xC8, 0x00, 0x01, 0x00});
  EXPECT_EQ(a.data[0], 0x60);
  ASSERT_TRUE(spy_->send(make_frame(0x000, {0x82, 0x05})));
  ASSERT_TRUE(lb::test::eventually(10s, [&] {
    const auto hb = spy_->frames(0x705);
    return std::count_if(hb.begin(), hb.end(), [](const auto& f) { return f.data[0] == 0x00; }) >= 2;
  }));
  a = sdo({0x40, 0x16, 0x10, 0x01, 0, 0, 0, 0});
  EXPECT_EQ(a.data[0], 0x43);
  EXPECT_EQ(a.data[4] | a.data[5] | a.data[6] | a.data[7], 0);
  // A node-ID beyond 127 is refused (0609 0030h, value range exceeded).
  a = sdo({0x23, 0x16, 0x10, 0x01, 0xC8, 0x00, 0x80, 0x00});
  EXPECT_EQ(a.data[0], 0x80);
  EXPECT_EQ(a.data[4] | a.data[5] << 8 | a.data[6] << 16 | a.data[7] << 24, 0x0609'0030);
}

}  // namespace
