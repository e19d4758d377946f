// PDOs as a line configuration reshapes them: a remapped TPDO on a 29-bit identifier sent every
// 2nd SYNC, an event-driven TPDO with inhibit time and event timer, an event-driven RPDO. The real
// bridge and simulator read the same overrides; the values still decode right, and the frames on
// the bus follow the transmission types.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/collector.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;

TEST(PdoOverrides, RemappedExtendedAndEventDrivenPdos) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string tag = std::to_string(::getpid());
  const std::string bus = "virtual:pdo-" + tag;
  const std::string tmp = ::testing::TempDir();
  const std::string cfg = tmp + "/pdo_" + tag + ".yaml";
  std::ofstream(cfg) << "line: pdo\ndds: {domain: 6}\nbuses:\n  - {name: p, interface: '" + bus + "'}\n"
                        "devices:\n"
                        "  - name: saw1\n"
                        "    bus: p\n"
                        "    node_id: 5\n"
                        "    profile: cia420-4\n"
                        "    version: '3.1'\n"
                        "    pdos:\n"
                        "      tpdo1: {transmission_type: 254, inhibit_time_100us: 500, event_timer_ms: 300}\n"
                        "      tpdo2: {cob_id: 0x20000285, transmission_type: 2, mapping: [0x60070020, 0x60010020]}\n"
                        "      rpdo1: {transmission_type: 255}\n"
                        "    simulation: {max_speed_m_per_min: 60, acceleration_m_per_min_s: 6000}\n";
  lb::test::BusSpy spy(bus);
  lb::test::ChildProcess sim({LB_BIN_SIM, "--config", cfg}, tmp + "/pdo_sim_" + tag + ".log");
  lb::test::ChildProcess bridge({LB_BIN_BRIDGE, "--config", cfg}, tmp + "/pdo_bridge_" + tag + ".log");
  const auto logs = [&] { return "--- bridge ---\n" + bridge.log() + "--- sim ---\n" + sim.log(); };

  auto dds = lb::ddsl::Participant::create({6, true, "pdo-test"});
  ASSERT_TRUE(dds) << dds.error().message;
  lb::test::Collector<msg::SawStatusPubSubType> status;
  lb::test::Collector<msg::SetpointResultPubSubType> results;
  ASSERT_TRUE(status.subscribe(**dds, lb::ddsl::topic_name("pdo", "saw1", "status"), lb::ddsl::QosKind::state));
  ASSERT_TRUE(results.subscribe(**dds, lb::ddsl::topic_name("pdo", "saw1", "setpoint_result"), lb::ddsl::QosKind::reply));
  auto writer = (*dds)->writer<msg::SawSetpointPubSubType>(lb::ddsl::topic_name("pdo", "saw1", "setpoint"), lb::ddsl::QosKind::command);
  ASSERT_TRUE(writer);
  ASSERT_TRUE(status.wait_last(15s, [](const msg::SawStatus& s) {
    return s.health().online() && s.health().nmt_state() == msg::NMT_OPERATIONAL;
  })) << logs();
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while ((writer->matched() == 0 || (*dds)->matched_writers(lb::ddsl::topic_name("pdo", "saw1", "setpoint_result")) == 0) &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(20ms);
  }

  // Quiet line: the event-driven RPDO1 is not repeated at every SYNC.
  spy.clear();
  std::this_thread::sleep_for(1000ms);
  EXPECT_TRUE(spy.frames(0x205).empty()) << "event-driven RPDO1 without a change";

  msg::SawSetpoint sp;
  sp.request_id(1);
  sp.saw_program_on(true);
  sp.sync_speed_percent(100);
  sp.product_length_m(0.5);
  writer->write(sp);
  ASSERT_TRUE(results.wait_last(5s, [](const msg::SetpointResult& r) { return r.request_id() == 1 && r.accepted(); })) << logs();

  // Values decode right through the swapped TPDO2 mapping: 60 m/min, and the saw cuts at 0.5 m.
  ASSERT_TRUE(status.wait(10s, [](const std::vector<msg::SawStatus>& v) {
    bool cut = false;
    for (std::size_t i = 1; i < v.size(); ++i) {
      if (v[i].status_word().saw_cutting() && !v[i - 1].status_word().saw_cutting() &&
          v[i - 1].actual_saw_counter_m() > 0.44 && v[i - 1].actual_saw_counter_m() < 0.5) {
        cut = true;
      }
    }
    return cut && v.back().product_speed_m_per_min() == 60.0;
  })) << logs();

  spy.clear();
  std::this_thread::sleep_for(1000ms);
  const auto frames = spy.frames();
  std::size_t syncs = 0, tpdo2_ext = 0, tpdo2_std = 0, tpdo1 = 0, rpdo1 = 0;
  for (const auto& f : frames) {
    if (f.id == 0x080 && !f.extended) ++syncs;
    if (f.id == 0x285) ++(f.extended ? tpdo2_ext : tpdo2_std);
    if (f.id == 0x185 && !f.extended) ++tpdo1;
    if (f.id == 0x205 && !f.extended) ++rpdo1;
  }
  EXPECT_GE(syncs, 40u);
  EXPECT_EQ(tpdo2_std, 0u) << "TPDO2 moved to a 29-bit identifier";
  EXPECT_NEAR(static_cast<double>(tpdo2_ext), syncs / 2.0, 3.0) << "TPDO2 after every 2nd SYNC";
  // TPDO1 carries the pulse counter, which changes at every SYNC: event-driven, it goes out at
  // most once per inhibit time of 50 ms, so about 20 a second instead of 50.
  EXPECT_GE(tpdo1, 10u);
  EXPECT_LE(tpdo1, 22u);
  EXPECT_LT(tpdo1, syncs);
  EXPECT_EQ(rpdo1, 0u) << "no set value changed in this second";

  // A new set value: RPDO1 goes out at once, once.
  spy.clear();
  sp.request_id(2);
  sp.product_length_m(0.4);
  writer->write(sp);
  ASSERT_TRUE(results.wait_last(5s, [](const msg::SetpointResult& r) { return r.request_id() == 2 && r.accepted(); }));
  std::this_thread::sleep_for(300ms);
  const auto sent = spy.frames(0x205);
  ASSERT_EQ(sent.size(), 1u) << logs();
  EXPECT_EQ(sent[0].data[4], 0xA0);  // 0.4 m = 4000 = 0FA0h
  EXPECT_EQ(sent[0].data[5], 0x0F);
  dds->reset();
  EXPECT_EQ(bridge.stop(), 0) << logs();
}
