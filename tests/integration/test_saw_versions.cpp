// Saw 1.0 and saw 3.1 side by side on one bus: both cut where they are told; what only 3.1 has
// (corrugated-pipe count mode, saw program enabled bit) is refused or absent on 1.0, with reasons.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/child_process.hpp"
#include "support/collector.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;

namespace {

bool cut_near(const std::vector<msg::SawStatus>& v, double length) {
  for (std::size_t i = 1; i < v.size(); ++i) {
    if (v[i].status_word().saw_cutting() && !v[i - 1].status_word().saw_cutting()) {
      const double at = v[i - 1].actual_saw_counter_m();
      if (at < length && at >= length - 0.05) return true;
    }
  }
  return false;
}

}  // namespace

TEST(SawVersions, OneZeroAndThreeOneSideBySide) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string tag = std::to_string(::getpid());
  const std::string tmp = ::testing::TempDir();
  const std::string cfg = tmp + "/versions_" + tag + ".yaml";
  std::ofstream(cfg) << "line: versions\ndds: {domain: 7}\nbuses:\n  - {name: b, interface: 'virtual:versions-" + tag +
                            "'}\n"
                            "devices:\n"
                            "  - {name: old_saw, bus: b, node_id: 3, profile: cia420-4, version: '1.0',"
                            " simulation: {max_speed_m_per_min: 60, acceleration_m_per_min_s: 6000}}\n"
                            "  - {name: new_saw, bus: b, node_id: 4, profile: cia420-4, version: '3.1',"
                            " simulation: {max_speed_m_per_min: 60, acceleration_m_per_min_s: 6000}}\n";
  lb::test::ChildProcess sim({LB_BIN_SIM, "--config", cfg}, tmp + "/versions_sim_" + tag + ".log");
  lb::test::ChildProcess bridge({LB_BIN_BRIDGE, "--config", cfg}, tmp + "/versions_bridge_" + tag + ".log");
  const auto logs = [&] { return "--- bridge ---\n" + bridge.log() + "--- sim ---\n" + sim.log(); };

  auto dds = lb::ddsl::Participant::create({7, true, "versions-test"});
  ASSERT_TRUE(dds) << dds.error().message;
  std::map<std::string, std::unique_ptr<lb::test::Collector<msg::SawStatusPubSubType>>> status;
  std::map<std::string, std::unique_ptr<lb::test::Collector<msg::SetpointResultPubSubType>>> results;
  std::map<std::string, lb::ddsl::Writer<msg::SawSetpointPubSubType>> writers;
  for (const std::string d : {"old_saw", "new_saw"}) {
    status[d] = std::make_unique<lb::test::Collector<msg::SawStatusPubSubType>>();
    results[d] = std::make_unique<lb::test::Collector<msg::SetpointResultPubSubType>>();
    ASSERT_TRUE(status[d]->subscribe(**dds, lb::ddsl::topic_name("versions", d, "status"), lb::ddsl::QosKind::state));
    ASSERT_TRUE(
        results[d]->subscribe(**dds, lb::ddsl::topic_name("versions", d, "setpoint_result"), lb::ddsl::QosKind::reply));
    auto w = (*dds)->writer<msg::SawSetpointPubSubType>(lb::ddsl::topic_name("versions", d, "setpoint"),
                                                        lb::ddsl::QosKind::command);
    ASSERT_TRUE(w);
    writers[d] = *w;
    ASSERT_TRUE(status[d]->wait_last(15s,
                                     [](const msg::SawStatus& s) {
                                       return s.health().online() && s.health().nmt_state() == msg::NMT_OPERATIONAL;
                                     }))
        << d << "\n"
        << logs();
  }
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  for (const std::string d : {"old_saw", "new_saw"}) {
    while ((writers[d].matched() == 0 ||
            (*dds)->matched_writers(lb::ddsl::topic_name("versions", d, "setpoint_result")) == 0) &&
           std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(20ms);
    }
  }
  const auto send = [&](const std::string& d, std::uint64_t id, double length, msg::SawCountMode mode) {
    msg::SawSetpoint sp;
    sp.request_id(id);
    sp.saw_program_on(true);
    sp.sync_speed_percent(100);
    sp.product_length_m(length);
    sp.count_mode(mode);
    writers[d].write(sp);
    msg::SetpointResult answer;
    EXPECT_TRUE(results[d]->wait(5s, [&](const std::vector<msg::SetpointResult>& v) {
      for (const auto& r : v) {
        if (r.request_id() == id) return answer = r, true;
      }
      return false;
    })) << logs();
    return answer;
  };

  // Corrugated-pipe mode is a 3.1 control bit: the 1.0 saw refuses it and says why.
  const auto refused = send("old_saw", 1, 0.4, msg::CORRUGATED_PIPE);
  EXPECT_FALSE(refused.accepted());
  EXPECT_NE(refused.reason().find("corrugated pipe mode is not available"), std::string::npos) << refused.reason();

  EXPECT_TRUE(send("old_saw", 2, 0.4, msg::SMOOTH_PIPE).accepted());
  EXPECT_TRUE(send("new_saw", 3, 0.6, msg::SMOOTH_PIPE).accepted());
  ASSERT_TRUE(status["old_saw"]->wait(10s, [](const auto& v) { return cut_near(v, 0.4); })) << logs();
  ASSERT_TRUE(status["new_saw"]->wait(10s, [](const auto& v) { return cut_near(v, 0.6); })) << logs();
  // Status bit 12 (saw program enabled) exists only in 3.1; the 1.0 simulator never sets it.
  EXPECT_TRUE(status["new_saw"]->samples().back().status_word().saw_program_enabled());
  EXPECT_FALSE(status["old_saw"]->samples().back().status_word().saw_program_enabled());
  dds->reset();
  EXPECT_EQ(bridge.stop(), 0) << logs();
}
