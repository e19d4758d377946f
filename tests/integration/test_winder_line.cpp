// The worked example of docs/adding-a-device-type.md: the winder, a device type that is data only
// (idl/winder.idl, config/profiles/example-winder-1.0.yaml, its entry in
// profiles/device_types.hpp). The simulator plays it from its profile, the bridge serves it, and
// this test reads it on DDS; every expected value is written by hand from the profile. Runs inside
// launch_scripts/netns-run.sh (CTest does that).
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "msgs/winderPubSubTypes.h"
#include "support/collector.hpp"
#include "support/line_harness.hpp"
#include "support/run_command.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;

TEST(WinderLine, TheSimulatedWinderIsOnDdsWithItsBitsAndValuesByName) {
  lb::test::LineHarness line("winder", 41);
  line.start("  - name: winder1\n    bus: b\n    node_id: 9\n    profile: lb-example-winder\n    version: '1.0'\n"
             "    heartbeat_timeout_ms: 400\n"
             "    simulation: {max_speed_m_per_min: 60, acceleration_m_per_min_s: 60, heartbeat_period_ms: 100}\n");
  lb::test::Collector<msg::WinderStatusPubSubType> status;
  ASSERT_TRUE(status.subscribe(line.dds(), line.topic("winder1", "status"), lb::ddsl::QosKind::state));

  // Idle: operational, ready to start (6030h bit 1, winder_ready_to_start), not running (bit 0).
  ASSERT_TRUE(status.wait_last(30s, [](const msg::WinderStatus& s) {
    return s.health().online() && s.health().nmt_state() == msg::NMT_OPERATIONAL &&
           s.status_word().winder_ready_to_start();
  })) << line.logs();
  {
    const auto s = status.samples().back();
    EXPECT_EQ(s.status_word().raw() & 0x0003, 0x0002) << "bit 1 ready, bit 0 not running";
    EXPECT_FALSE(s.status_word().winder_running());
  }

  // The set values: extruder running (6020h bit 6) and 12.5 % (6002h, 0.01 %: raw 1250), echoed
  // by the winder in 6004h (TPDO2).
  auto writer = line.dds().writer<msg::WinderSetpointPubSubType>(line.topic("winder1", "setpoint"),
                                                                 lb::ddsl::QosKind::command);
  ASSERT_TRUE(writer) << writer.error().message;
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (writer->matched() == 0 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(20ms);
  ASSERT_GT(writer->matched(), 0);
  msg::WinderSetpoint sp;
  sp.request_id(1);
  sp.extruder_running(true);
  sp.speed_set_percent(12.5);
  writer->write(sp);
  EXPECT_TRUE(status.wait_last(30s, [](const msg::WinderStatus& s) {
    return s.control_word().extruder_running() && (s.control_word().raw() & 0x0040) != 0 &&
           s.speed_set_percent() == 12.5 && s.speed_set_echo_percent() == 12.5;
  })) << line.logs();

  // A momentary command named by the IDL's control word (6020h bit 1, winder_start): the winder runs.
  const auto started = line.command("winder1", "winder_start");
  EXPECT_TRUE(started.success()) << started.message();
  EXPECT_TRUE(status.wait_last(30s, [](const msg::WinderStatus& s) {
    return s.status_word().winder_running() && (s.status_word().raw() & 0x0001) != 0;
  })) << line.logs();

  // linebridge-cli knows the type by its registry entry and IDL binding alone.
  const auto set = lb::test::run_command(
      {LB_BIN_CLI, "--config", line.bridge_config(), "set", "winder1", "--speed-percent", "20"});
  EXPECT_EQ(set.exit_code, 0) << set.output;
  EXPECT_TRUE(status.wait_last(30s, [](const msg::WinderStatus& s) { return s.speed_set_percent() == 20.0; }))
      << line.logs();
  const auto echo = lb::test::run_command(
      {LB_BIN_CLI, "--config", line.bridge_config(), "echo", "winder1", "status", "--duration", "2"});
  EXPECT_EQ(echo.exit_code, 0) << echo.output;
  EXPECT_NE(echo.output.find("winder1 "), std::string::npos) << echo.output;
  EXPECT_NE(echo.output.find("winder_running"), std::string::npos) << "status bits by their IDL names\n" << echo.output;
}
