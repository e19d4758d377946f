// From one line PC to a plant, with the real executables inside the private network namespace:
// three lines found through a real fast-discovery-server with multicast switched off; two lines on
// one DDS domain that do not disturb each other; a site's XML profile that changes what a site may
// and not what the contract keeps; the gateway's systemd notifications (READY, WATCHDOG, STOPPING).
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <memory>
#include <sstream>
#include <thread>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/child_process.hpp"
#include "support/collector.hpp"
#include "support/fastdds_profiles_xml.hpp"
#include "support/line_harness.hpp"
#include "support/notify_socket.hpp"
#include "support/run_command.hpp"
#include "support/spy_waits.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using lb::test::ChildProcess;
using lb::test::run_command;

namespace {

std::string tag() { return std::to_string(::getpid()); }

// One line of its own: a saw on its own virtual bus, the simulator and the bridge.
struct Line {
  std::string name;
  std::string config;
  std::unique_ptr<ChildProcess> sim, bridge;
  std::string logs() const { return "--- " + name + " bridge ---\n" + bridge->log() + "--- sim ---\n" + sim->log(); }
};

Line start_line(const std::string& name, const std::string& dds) {
  Line l;
  l.name = name;
  l.config = ::testing::TempDir() + "/plant_" + name + "_" + tag() + ".yaml";
  std::ofstream(l.config)
      << "line: " << name << "\ndds: " << dds << "\nbuses:\n  - {name: b, interface: 'virtual:plant-" << name << "-"
      << tag() << "', master_node_id: 1}\ndevices:\n"
      << "  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 500}\n";
  const auto log = ::testing::TempDir() + "/plant_" + name + "_" + tag();
  l.sim = std::make_unique<ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", l.config}, log + "_sim.log");
  l.bridge = std::make_unique<ChildProcess>(std::vector<std::string>{LB_BIN_BRIDGE, "--config", l.config},
                                            log + "_bridge.log");
  return l;
}

bool wait_for(std::chrono::seconds timeout, const std::function<bool()>& cond) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!cond()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(50ms);
  }
  return true;
}

TEST(Plant, ThreeLinesThroughADiscoveryServerWithoutMulticast) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  // No multicast in this namespace from here on: simple discovery cannot work, only the server.
  ASSERT_EQ(std::system("ip route del 224.0.0.0/4 && ip link set lo multicast off"), 0);
  ChildProcess server({"/usr/bin/fast-discovery-server", "-i", "0", "-l", "127.0.0.1", "-p", "11811"},
                      ::testing::TempDir() + "/plant_ds_" + tag() + ".log");
  ASSERT_TRUE(server.started());
  const std::string ds = "discovery_servers: [{id: 0, address: 127.0.0.1, port: 11811}]";
  // Two lines as a plant network would have them (all interfaces), one kept on localhost.
  std::vector<Line> lines;
  lines.push_back(start_line("plant_a", "{domain: 7, localhost_only: false, " + ds + "}"));
  lines.push_back(start_line("plant_b", "{domain: 7, localhost_only: false, " + ds + "}"));
  lines.push_back(start_line("plant_c", "{domain: 7, localhost_only: true, " + ds + "}"));

  // One client (a super client of the server) sees every line's topics and bridges.
  lb::test::CommandResult topics;
  const bool all = wait_for(40s, [&] {
    topics = run_command({LB_BIN_CLI, "--config", lines[0].config, "topics", "--all", "--wait", "4"});
    return topics.output.find("rt/plant_a/saw1/status") != std::string::npos &&
           topics.output.find("rt/plant_b/saw1/status") != std::string::npos &&
           topics.output.find("rt/plant_c/saw1/status") != std::string::npos;
  });
  std::string logs = server.log();
  for (const auto& l : lines) logs += l.logs();
  ASSERT_TRUE(all) << topics.output << logs;
  for (const char* expected : {"rt/plant_b/bridge/diagnostics", "rq/plant_c/bridge/nmtRequest", "linebridge/plant_a",
                               "linebridge/plant_b", "linebridge/plant_c", "linebridge_msgs::msg::dds_::SawStatus_"}) {
    EXPECT_NE(topics.output.find(expected), std::string::npos) << expected << "\n" << topics.output;
  }
  // Without --all only the client's own line.
  const auto own = run_command({LB_BIN_CLI, "--config", lines[1].config, "topics", "--wait", "3"});
  EXPECT_EQ(own.exit_code, 0) << own.output;
  EXPECT_NE(own.output.find("rt/plant_b/saw1/status"), std::string::npos) << own.output;
  EXPECT_EQ(own.output.find("plant_a"), std::string::npos) << own.output;

  // Requests and replies travel too: a service call to another line's bridge through the server.
  const auto identity = run_command({LB_BIN_CLI, "--config", lines[2].config, "identity", "saw1", "--timeout", "20"});
  EXPECT_EQ(identity.exit_code, 0) << identity.output << lines[2].logs();
  EXPECT_NE(identity.output.find("vendor_id: 0x4C420000"), std::string::npos) << identity.output;

  // The control: the same client without the server finds nothing (multicast is off here).
  const auto simple = ::testing::TempDir() + "/plant_simple_" + tag() + ".yaml";
  std::ofstream(simple) << "line: plant_a\ndds: {domain: 7, localhost_only: false}\nbuses: []\ndevices: []\n";
  const auto none = run_command({LB_BIN_CLI, "--config", simple, "topics", "--all", "--wait", "4"});
  EXPECT_EQ(none.exit_code, 1) << none.output;
  EXPECT_NE(none.output.find("no topic of any line discovered"), std::string::npos) << none.output;

  for (auto& l : lines) EXPECT_EQ(l.bridge->stop(), 0) << l.logs();
}

// Two bridges with different line names on one domain: set values, services and diagnostics of
// one never reach the other, although device names, node-IDs and topics' shapes are the same.
TEST(Plant, TwoLinesOnOneDomainDoNotDisturbEachOther) {
  constexpr std::uint32_t kDomain = 21;
  lb::test::LineHarness north("north", kDomain), south("south", kDomain);
  const std::string saw =
      "  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 500}\n";
  north.start(saw, "", ", master_node_id: 1");
  south.start(saw, "", ", master_node_id: 1");
  lb::test::Collector<msg::SawStatusPubSubType> north_status, south_status;
  lb::test::Collector<msg::SetpointResultPubSubType> north_results, south_results;
  lb::test::Collector<msg::DiagnosticsPubSubType> north_diag, south_diag;
  ASSERT_TRUE(north_status.subscribe(north.dds(), north.topic("saw1", "status"), lb::ddsl::QosKind::state));
  ASSERT_TRUE(south_status.subscribe(north.dds(), south.topic("saw1", "status"), lb::ddsl::QosKind::state));
  ASSERT_TRUE(north_results.subscribe(north.dds(), north.topic("saw1", "setpoint_result"), lb::ddsl::QosKind::reply));
  ASSERT_TRUE(south_results.subscribe(north.dds(), south.topic("saw1", "setpoint_result"), lb::ddsl::QosKind::reply));
  ASSERT_TRUE(north_diag.subscribe(north.dds(), north.topic("bridge", "diagnostics"), lb::ddsl::QosKind::state));
  ASSERT_TRUE(south_diag.subscribe(north.dds(), south.topic("bridge", "diagnostics"), lb::ddsl::QosKind::state));
  const auto online = [](const msg::SawStatus& s) {
    return s.health().online() && s.health().nmt_state() == msg::NMT_OPERATIONAL;
  };
  ASSERT_TRUE(north_status.wait_last(20000ms, online)) << north.logs();
  ASSERT_TRUE(south_status.wait_last(20000ms, online)) << south.logs();

  // A set value for north's saw1: north's bus carries it, south's never does.
  auto writer = north.dds().writer<msg::SawSetpointPubSubType>(north.topic("saw1", "setpoint"),
                                                               lb::ddsl::QosKind::command);
  ASSERT_TRUE(writer);
  ASSERT_TRUE(wait_for(10s, [&] {
    return writer->matched() > 0 && north.dds().matched_writers(north.topic("saw1", "setpoint_result")) > 0;
  }));
  msg::SawSetpoint sp;
  sp.request_id(4242);
  sp.saw_program_on(true);
  sp.sync_speed_percent(50);
  sp.product_length_m(1.234);
  south.spy().clear();
  writer->write(sp);
  ASSERT_TRUE(north_results.wait_last(10000ms, [](const msg::SetpointResult& r) {
    return r.request_id() == 4242 && r.accepted();
  })) << north.logs();
  const auto carries = [](const lb::can::CanFrame& f) {
    return f.len == 8 && f.data[4] == 0x34 && f.data[5] == 0x30;
  };  // 12340 x 0.1 mm
  ASSERT_TRUE(wait_for(5s, [&] {
    for (const auto& f : north.spy().frames(0x203)) {
      if (carries(f)) return true;
    }
    return false;
  }));
  // The marker before the negative check: south's bridge's own heartbeat (701h, every second)
  // stamped after north's bus carried the value.
  ASSERT_TRUE(lb::test::wait_frames_after(south.spy(), 0x701, lb::test::bus_now_ns())) << south.logs();
  for (const auto& f : south.spy().frames(0x203)) EXPECT_FALSE(carries(f)) << "north's set value on south's bus";
  EXPECT_EQ(south_results.size(), 0U) << "south answered north's set value";

  // NMT stop through north's line-wide service: only north's saw stops.
  south.spy().clear();
  const auto stopped = north.nmt("saw1", linebridge_msgs::srv::NMT_STOP);
  EXPECT_TRUE(stopped.success()) << stopped.message();
  ASSERT_TRUE(wait_for(5s, [&] { return !north.spy().frames(0x000).empty(); }));
  ASSERT_TRUE(lb::test::wait_frames_after(south.spy(), 0x701, lb::test::bus_now_ns())) << south.logs();
  EXPECT_TRUE(south.spy().frames(0x000).empty()) << "an NMT command on south's bus";
  EXPECT_TRUE(south_status.samples().back().health().nmt_state() == msg::NMT_OPERATIONAL);

  // Each bridge's diagnostics name its own line and devices only.
  ASSERT_TRUE(north_diag.wait_last(5000ms, [](const msg::Diagnostics& d) { return !d.nodes().empty(); }));
  ASSERT_TRUE(south_diag.wait_last(5000ms, [](const msg::Diagnostics& d) { return !d.nodes().empty(); }));
  for (auto* diag : {&north_diag, &south_diag}) {
    const auto d = diag->samples().back();
    EXPECT_EQ(d.buses().size(), 1U);
    ASSERT_EQ(d.nodes().size(), 1U);
  }
  EXPECT_EQ(north_diag.samples().back().line(), "north");
  EXPECT_EQ(south_diag.samples().back().line(), "south");
  EXPECT_EQ(north_diag.samples().back().buses()[0].interface_uri(), north.bus());
  EXPECT_EQ(south_diag.samples().back().buses()[0].interface_uri(), south.bus());
  EXPECT_NE(south_diag.samples().back().nodes()[0].nmt_state(), msg::NMT_STOPPED);
}

// A site profile: per topic, timing changes (deadline), the contract's reliability and durability do
// not; the bridge says what it did not apply. A late joiner still gets the current status.
TEST(Plant, SiteProfileChangesTimingNotTheContract) {
  const auto xml = ::testing::TempDir() + "/plant_site_" + tag() + ".xml";
  // What a site may change (the deadline) and what it may not (reliability, durability).
  std::ofstream(xml) << lb::test::fastdds_profiles_xml(
      lb::test::data_writer_profile("rt/site/saw1/status", "<reliability><kind>BEST_EFFORT</kind></reliability>"
                                                           "<durability><kind>VOLATILE</kind></durability>"
                                                           "<deadline><period><sec>2</sec></period></deadline>"));
  auto line = start_line("site", "{domain: 9, profiles_file: '" + xml + "'}");
  lb::test::CommandResult topics;
  ASSERT_TRUE(wait_for(30s,
                       [&] {
                         topics = run_command({LB_BIN_CLI, "--config", line.config, "topics", "--wait", "2"});
                         return topics.output.find("rt/site/saw1/status") != std::string::npos;
                       }))
      << topics.output << line.logs();
  std::string status_line;
  std::istringstream in(topics.output);
  for (std::string l; std::getline(in, l);) {
    if (l.rfind("rt/site/saw1/status", 0) == 0) status_line = l;
  }
  EXPECT_NE(status_line.find("reliable, transient-local, deadline 2 s"), std::string::npos) << topics.output;
  EXPECT_NE(line.bridge->log().find("rt/site/saw1/status: reliability is the DDS contract's"), std::string::npos)
      << line.logs();
  EXPECT_NE(line.bridge->log().find("durability is the DDS contract's"), std::string::npos) << line.logs();

  // Transient-local kept: a reader that joins now still gets the saw's current status.
  auto dds = lb::ddsl::Participant::create({9, true, "site-late"});
  ASSERT_TRUE(dds);
  lb::test::Collector<msg::SawStatusPubSubType> status;
  ASSERT_TRUE(status.subscribe(**dds, "rt/site/saw1/status", lb::ddsl::QosKind::state));
  EXPECT_TRUE(status.wait_last(10000ms, [](const msg::SawStatus& s) { return s.health().online(); })) << line.logs();
}

// The gateway under a service manager: READY=1 once its bus loops run, WATCHDOG=1 while they do,
// STOPPING=1 at SIGTERM, then exit 0.
TEST(Plant, GatewayNotifiesTheServiceManager) {
  lb::test::NotifySocket socket;
  ::setenv("WATCHDOG_USEC", "1000000", 1);
  auto line = start_line("notify", "{domain: 11}");
  ::unsetenv("WATCHDOG_USEC");
  ::unsetenv("NOTIFY_SOCKET");  // only the bridge started above has it
  std::string first = socket.next(20s);
  EXPECT_EQ(first.rfind("READY=1", 0), 0U) << first << line.logs();
  EXPECT_NE(first.find("1 bus loop(s) running"), std::string::npos) << first;
  EXPECT_NE(socket.during(2500ms).find("WATCHDOG=1"), std::string::npos) << line.logs();
  ::kill(line.bridge->pid(), SIGTERM);
  EXPECT_NE(socket.during(2s).find("STOPPING=1"), std::string::npos);
  EXPECT_EQ(line.bridge->stop(), 0) << line.logs();
  EXPECT_NE(line.bridge->log().find("systemd watchdog: every bus loop must show progress within 1000 ms"),
            std::string::npos);
}

}  // namespace
