// A bridge in the monitor role beside a running line: it decodes the devices' TPDOs and the line
// controller's RPDOs, heartbeats and EMCYs, refuses every command with the reason, and puts no
// frame on the bus. Real processes: linebridge (monitor), linebridge-sim --role devices and
// --role controller, this test as DDS participant and passive bus member.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <set>
#include <thread>

#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/child_process.hpp"
#include "support/collector.hpp"
#include "support/eventually.hpp"
#include "support/monitor_silence.hpp"
#include "support/monitored_line.hpp"
#include "support/service_clients.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using lb::ddsl::QosKind;

TEST(MonitorRole, DecodesBothDirectionsAndNeverTransmits) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  // The line (simulated devices and controller) owns the bus; the bridge only listens.
  lb::test::MonitoredLine line("mon", 5,
                               "devices:\n"
                               "  - name: saw1\n"
                               "    bus: m\n"
                               "    node_id: 5\n"
                               "    profile: cia420-4\n"
                               "    version: '3.1'\n"
                               "    heartbeat_timeout_ms: 400\n"
                               "    simulation:\n"
                               "      max_speed_m_per_min: 60\n"
                               "      controller_values: {control_word: 1, saw_sync_speed_set_value: 5000, "
                               "product_length_set_value: 15000}\n");
  const auto logs = [&] { return line.logs(); };

  auto dds = lb::ddsl::Participant::create({5, true, "monitor-test"});
  ASSERT_TRUE(dds) << dds.error().message;
  lb::test::Collector<msg::SawStatusPubSubType> status;
  lb::test::Collector<msg::SetpointResultPubSubType> results;
  ASSERT_TRUE(status.subscribe(**dds, lb::ddsl::topic_name("mon", "saw1", "status"), QosKind::state));
  ASSERT_TRUE(results.subscribe(**dds, lb::ddsl::topic_name("mon", "saw1", "setpoint_result"), QosKind::reply));
  lb::test::Collector<msg::DiagnosticsPubSubType> diag;
  ASSERT_TRUE(diag.subscribe(**dds, lb::ddsl::topic_name("mon", "bridge", "diagnostics"), QosKind::state));
  // Without a controller the devices sit in pre-operational and send only heartbeats.
  ASSERT_TRUE(status.wait_last(10s, [](const msg::SawStatus& s) {
    return s.health().online() && s.health().nmt_state() == msg::NMT_PRE_OPERATIONAL;
  })) << logs();

  // Phase 1: every way of making the bridge transmit is refused with the reason...
  line.spy().clear();
  // The services are line-wide (mon/bridge/<service>); the request names the device.
  srv::Nmt_Request start;
  start.device("saw1");
  start.command(srv::NMT_START);
  ASSERT_NO_FATAL_FAILURE(
      lb::test::expect_refused_by_monitor<lb::test::NmtClient>(**dds, lb::ddsl::line_service_path("mon", "nmt"),
                                                               start));
  srv::SdoRead_Request rq;
  rq.device("saw1");
  rq.index(0x1000);
  rq.data_type("UNSIGNED32");
  ASSERT_NO_FATAL_FAILURE(
      lb::test::expect_refused_by_monitor<lb::test::ReadClient>(**dds, lb::ddsl::line_service_path("mon", "sdo_read"),
                                                                rq));
  srv::Command_Request cut;
  cut.device("saw1");
  cut.command("manual_cut");
  ASSERT_NO_FATAL_FAILURE(
      lb::test::expect_refused_by_monitor<lb::test::CommandClient>(**dds, lb::ddsl::line_service_path("mon", "command"),
                                                                   cut));

  auto sp_writer = (*dds)->writer<msg::SawSetpointPubSubType>(lb::ddsl::topic_name("mon", "saw1", "setpoint"),
                                                              QosKind::command);
  ASSERT_TRUE(sp_writer);
  ASSERT_TRUE(lb::test::eventually(10s, [&] { return sp_writer->matched() > 0; })) << logs();
  msg::SawSetpoint sp;
  sp.request_id(7);
  sp.saw_program_on(true);
  sp.sync_speed_percent(10);
  sp.product_length_m(1);
  sp_writer->write(sp);
  ASSERT_TRUE(results.wait_last(10s, [](const msg::SetpointResult& x) { return x.request_id() == 7; })) << logs();
  EXPECT_FALSE(results.samples().back().accepted());
  EXPECT_NE(results.samples().back().reason().find("monitor role"), std::string::npos);

  // ... and over ten more of the device's heartbeats (a second) nothing but those heartbeats is
  // on the bus: no NMT, no SYNC, no RPDO, no SDO request, no heartbeat of a master.
  EXPECT_EQ(line.ids_after_heartbeats(5, 10), (std::set<std::uint32_t>{0x705})) << logs();

  // Phase 2: a line controller starts the device and drives it; the bridge decodes its RPDO1
  // (program on, 50.00 %, 1.5000 m) and the device's TPDOs.
  lb::test::ChildProcess controller({LB_BIN_SIM, "--config", line.line_config(), "--role", "controller"},
                                    ::testing::TempDir() + "/mon_ctl_" + std::to_string(::getpid()) + ".log");
  ASSERT_TRUE(status.wait_last(10s,
                               [](const msg::SawStatus& s) {
                                 return s.health().nmt_state() == msg::NMT_OPERATIONAL &&
                                        s.control_word().saw_program_on() && s.sync_speed_set_percent() == 50.0 &&
                                        s.product_length_set_m() == 1.5 && s.product_speed_m_per_min() > 0;
                               }))
      << logs() << "--- controller ---\n"
      << controller.log();
  EXPECT_TRUE(status.samples().back().status_word().saw_ready());
  // The bridge never tried to transmit (its diagnostics after everything above).
  ASSERT_NO_FATAL_FAILURE(lb::test::expect_monitor_never_sent(diag, logs()));
  dds->reset();
  EXPECT_EQ(line.bridge().stop(), 0);
}
