// A device's status sample per SYNC cycle (status_publish, docs/dds-contract.md). The real bridge
// (monitor role) watches a bus on which this test plays a CiA 420-4 saw by hand: its heartbeat,
// the SYNC and the saw's two synchronous TPDOs (profile 3.1 default mapping, CiA 420-4 tables
// 2-9: TPDO1 = 6030h status word + 6000h counter value; TPDO2 = 6001h actual saw counter in
// 0.1 mm + 6007h product speed in mm/min), TPDO2 a few milliseconds after TPDO1. Cycle i carries
// counter value 1000 + i, saw counter i x 0.1 mm and speed i mm/min.
//   per_cycle (the default): one sample per cycle with both TPDOs of it, never one with TPDO1 of
//     a cycle and TPDO2 of the cycle before; a cycle whose TPDO2 never comes is published at the
//     cycle's end (one SYNC interval after its SYNC) when the next SYNC does not come.
//   per_frame: a sample per TPDO, so the mixed sample shows.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <fstream>
#include <string>
#include <thread>

#include "can/detail.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/sawPubSubTypes.h"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/collector.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;

namespace {

constexpr std::uint8_t kNode = 5;
constexpr auto kSyncPeriod = 200ms;  // the test's SYNC: the deadline dwarfs a loaded machine's sleeps
constexpr auto kTpdoGap = 3ms;       // TPDO2 after TPDO1: another burst for the bridge's loop
constexpr int kCycles = 12;

class StatusPerCycle : public ::testing::Test {
 protected:
  void start(const std::string& status_publish, std::uint32_t domain) {
    ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
    const auto tag = std::to_string(::getpid()) + "-" + status_publish;
    const auto dir = ::testing::TempDir();
    const auto bus = "virtual:cycle-" + tag;
    spy_ = std::make_unique<lb::test::BusSpy>(bus);
    const auto config = dir + "/cycle_" + tag + ".yaml";
    std::ofstream(config) << "line: cyc\n"
                          << (status_publish.empty() ? "" : "status_publish: " + status_publish + "\n")
                          << "dds: {domain: " << domain << "}\n"
                          << "buses:\n  - {name: m, interface: '" << bus
                          << "', role: monitor, sync_period_ms: " << kSyncPeriod.count() << "}\n"
                          << "devices:\n  - {name: saw1, bus: m, node_id: " << int{kNode}
                          << ", profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 2000}\n";
    bridge_ = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_BRIDGE, "--config", config},
                                                       dir + "/cycle_bridge_" + tag + ".log");
    auto dds = lb::ddsl::Participant::create({domain, true, "cycle-test"});
    ASSERT_TRUE(dds) << dds.error().message;
    dds_ = std::move(*dds);
    ASSERT_TRUE(status_.subscribe(*dds_, lb::ddsl::topic_name("cyc", "saw1", "status"), lb::ddsl::QosKind::state));
    // Operational, heard: the bridge publishes the saw online before the first cycle (heartbeats
    // until then: the bridge's process may not be on the bus yet).
    const auto online = [](const msg::SawStatus& s) {
      return s.health().online() && s.health().nmt_state() == msg::NMT_OPERATIONAL;
    };
    const auto until = std::chrono::steady_clock::now() + 60s;
    bool heard = false;
    while (!heard && std::chrono::steady_clock::now() < until) {
      ASSERT_TRUE(spy_->send(lb::can::make_frame(0x700 + kNode, {0x05})));
      heard = status_.wait_last(200ms, online);
    }
    ASSERT_TRUE(heard) << bridge_->log();
  }
  void TearDown() override {
    dds_.reset();
    if (bridge_) {
      EXPECT_EQ(bridge_->stop(), 0);
    }
  }

  static void put32(lb::can::CanFrame& f, std::size_t at, std::uint32_t v) {
    for (std::size_t b = 0; b < 4; ++b) f.data[at + b] = static_cast<std::uint8_t>(v >> (8 * b));
  }
  // One SYNC cycle of the saw: heartbeat, SYNC, TPDO1, then (unless left out) TPDO2.
  void cycle(std::uint32_t i, bool with_tpdo2 = true) {
    ASSERT_TRUE(spy_->send(lb::can::make_frame(0x700 + kNode, {0x05})));
    ASSERT_TRUE(spy_->send(lb::can::make_frame(0x080, {})));
    lb::can::CanFrame t1 = lb::can::make_frame(0x180 + kNode, {0x01, 0x00, 0, 0, 0, 0});  // 6030h: saw ready
    put32(t1, 2, 1000 + i);
    ASSERT_TRUE(spy_->send(t1));
    if (!with_tpdo2) return;
    std::this_thread::sleep_for(kTpdoGap);  // stays: the gap between the saw's two TPDOs
    lb::can::CanFrame t2 = lb::can::make_frame(0x280 + kNode, {0, 0, 0, 0, 0, 0, 0, 0});
    put32(t2, 0, i);  // 6001h: i x 0.1 mm
    put32(t2, 4, i);  // 6007h: i mm/min
    ASSERT_TRUE(spy_->send(t2));
  }
  // Cycles 1..kCycles at the SYNC period; returns once the last one's sample is in.
  void run_cycles() {
    for (std::uint32_t i = 1; i <= kCycles; ++i) {
      const auto next = std::chrono::steady_clock::now() + kSyncPeriod;
      ASSERT_NO_FATAL_FAILURE(cycle(i));
      std::this_thread::sleep_until(next);  // stays: the SYNC period the test plays
    }
    ASSERT_TRUE(status_.wait_last(30s, [](const msg::SawStatus& s) {
      return s.counter_value() == 1000 + kCycles && std::llround(s.product_speed_m_per_min() * 1000) == kCycles;
    })) << bridge_->log();
  }
  // Samples of cycle i (counter value 1000 + i): (both TPDOs of i, TPDO1 of i with TPDO2 of i - 1).
  std::pair<int, int> count(std::uint32_t i) {
    int whole = 0;
    int mixed = 0;
    for (const auto& s : status_.samples()) {
      if (s.counter_value() != 1000 + i) continue;
      const auto speed = std::llround(s.product_speed_m_per_min() * 1000);  // mm/min
      const auto counter = std::llround(s.actual_saw_counter_m() * 10000);  // 0.1 mm
      if (speed == i && counter == i) ++whole;
      if (speed == i - 1) ++mixed;
    }
    return {whole, mixed};
  }

  std::unique_ptr<lb::test::BusSpy> spy_;
  std::unique_ptr<lb::test::ChildProcess> bridge_;
  std::unique_ptr<lb::ddsl::Participant> dds_;
  lb::test::Collector<msg::SawStatusPubSubType> status_;
};

}  // namespace

TEST_F(StatusPerCycle, OneSamplePerCycleWithBothTpdosAndTheDeadlinePublishesACycleMissingOne) {
  ASSERT_NO_FATAL_FAILURE(start("", 71));  // per_cycle: the default
  ASSERT_NO_FATAL_FAILURE(run_cycles());
  for (std::uint32_t i = 2; i <= kCycles; ++i) {
    const auto [whole, mixed] = count(i);
    EXPECT_EQ(whole, 1) << "cycle " << i << ": samples with both of its TPDOs\n" << bridge_->log();
    EXPECT_EQ(mixed, 0) << "cycle " << i << ": samples with its TPDO1 and the TPDO2 before\n" << bridge_->log();
  }
  EXPECT_EQ(status_.gaps(), 0u);

  // A cycle whose TPDO2 never comes: its TPDO1 is published at the deadline, one SYNC interval
  // (about 200 ms) after its SYNC, though the next SYNC does not come (this test holds it back).
  const auto sent = std::chrono::steady_clock::now();
  ASSERT_NO_FATAL_FAILURE(cycle(kCycles + 1, false));
  ASSERT_TRUE(status_.wait_last(4s, [](const msg::SawStatus& s) { return s.counter_value() == 1000 + kCycles + 1; }))
      << "the cycle without its TPDO2 was not published before the next SYNC\n"
      << bridge_->log();
  const auto waited = std::chrono::steady_clock::now() - sent;
  std::printf("a cycle missing its TPDO2: published %.1f ms after its SYNC (deadline: the %lld ms interval)\n",
              std::chrono::duration<double, std::milli>(waited).count(), static_cast<long long>(kSyncPeriod.count()));
  const auto last = status_.samples().back();
  EXPECT_EQ(std::llround(last.product_speed_m_per_min() * 1000), kCycles) << "TPDO2 is the previous cycle's";
}

TEST_F(StatusPerCycle, PerFramePublishesEachTpdoAsItComes) {
  ASSERT_NO_FATAL_FAILURE(start("per_frame", 72));
  ASSERT_NO_FATAL_FAILURE(run_cycles());
  int mixed_cycles = 0;
  for (std::uint32_t i = 2; i <= kCycles; ++i) {
    const auto [whole, mixed] = count(i);
    EXPECT_EQ(whole, 1) << "cycle " << i << "\n" << bridge_->log();
    if (mixed > 0) ++mixed_cycles;
  }
  // TPDO1 went out on its own before TPDO2 came: the sample between them shows (3 ms apart: another
  // burst in nearly every cycle).
  EXPECT_GE(mixed_cycles, (kCycles - 1) / 2) << bridge_->log();
}
