// A feeder control box end to end: the real simulator (4 feeders) and the real bridge as separate
// processes on a virtual bus, this test as DDS participant and passive bus member. Master role:
// per-feeder status by SDO, an injected fault -> EMCY FF10h -> feeder_error event with the 6007h
// detail read by SDO, cleared by a feeder command; invalid commands refused before CAN; the bridge
// as loom controller. Monitor role: hand-built loom-controller RPDOs decoded, nothing transmitted.
// Runs inside launch_scripts/netns-run.sh (CTest does that).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <memory>

#include <chrono>
#include <fstream>
#include <set>
#include <thread>

#include "dds/incarnation.hpp"
#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/feederPubSubTypes.h"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/collector.hpp"
#include "support/eventually.hpp"
#include "support/monitor_silence.hpp"
#include "support/monitored_line.hpp"
#include "support/spy_waits.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using lb::ddsl::QosKind;

namespace {

constexpr std::uint8_t kNode = 10;
using CommandClient =
    lb::ddsl::ServiceClient<srv::FeederCommand_RequestPubSubType, srv::FeederWrite_ResponsePubSubType>;
using FunctionsClient =
    lb::ddsl::ServiceClient<srv::FeederFunctions_RequestPubSubType, srv::FeederWrite_ResponsePubSubType>;
using SdoWriteClient = lb::ddsl::ServiceClient<srv::SdoWrite_RequestPubSubType, srv::SdoWrite_ResponsePubSubType>;
using PressClient = lb::ddsl::ServiceClient<srv::Command_RequestPubSubType, srv::Command_ResponsePubSubType>;

std::string device_yaml(const std::string& bus) {
  return "devices:\n"
         "  - name: feeders\n"
         "    bus: " +
         bus +
         "\n"
         "    node_id: 10\n"
         "    profile: cia414-2\n"
         "    version: '1.1'\n"
         "    heartbeat_timeout_ms: 400\n"
         "    simulation: {heartbeat_period_ms: 100}\n";
}

// SDO downloads (initiate, any size) of the bridge to the box for one object.
std::size_t sdo_downloads(lb::test::BusSpy& spy, std::uint16_t index) {
  std::size_t n = 0;
  for (const auto& f : spy.frames(0x600 + kNode)) {
    if ((f.data[0] & 0xE0) == 0x20 && f.data[1] == (index & 0xFF) && f.data[2] == (index >> 8)) ++n;
  }
  return n;
}

srv::FeederWrite_Response command(CommandClient& c, std::uint8_t feeder, const std::string& name) {
  srv::FeederCommand_Request req;
  req.feeder(feeder);
  req.command(name);
  auto r = c.call(req, 10s);
  EXPECT_TRUE(r) << r.error().message;
  return r ? *r : srv::FeederWrite_Response{};
}

}  // namespace

TEST(FeederLine, StatusFaultEventsCommandsAndLoomPlay) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string tag = std::to_string(::getpid());
  const std::string bus = "virtual:it-feed-" + tag;
  const std::string tmp = ::testing::TempDir();
  const std::string cfg = tmp + "/feeder_line_" + tag + ".yaml";
  std::ofstream(cfg) << "line: itest\ndds: {domain: 7, localhost_only: true}\nbuses:\n"
                        "  - {name: loom, interface: '" +
                            bus + "', role: master, sync_period_ms: 20}\n" + device_yaml("loom");

  lb::test::BusSpy spy(bus);
  lb::test::ChildProcess sim({LB_BIN_SIM, "--config", cfg}, tmp + "/feed_sim_" + tag + ".log");
  lb::test::ChildProcess bridge({LB_BIN_BRIDGE, "--config", cfg}, tmp + "/feed_bridge_" + tag + ".log");
  const auto logs = [&] { return "--- bridge ---\n" + bridge.log() + "--- sim ---\n" + sim.log(); };

  auto dds = lb::ddsl::Participant::create({7, true, "feeder-test"});
  ASSERT_TRUE(dds) << dds.error().message;
  const auto topic = [](const char* t) { return lb::ddsl::topic_name("itest", "feeders", t); };
  lb::test::Collector<msg::FeederStatusPubSubType> status;
  lb::test::Collector<msg::FeederErrorPubSubType> errors;
  lb::test::Collector<msg::FeederUnwindingPubSubType> unwinding;
  lb::test::Collector<msg::SetpointResultPubSubType> loom_results;
  ASSERT_TRUE(status.subscribe(**dds, topic("status"), QosKind::state));
  ASSERT_TRUE(errors.subscribe(**dds, topic("feeder_error"), QosKind::event));
  ASSERT_TRUE(unwinding.subscribe(**dds, topic("unwinding"), QosKind::event));
  // Events reach only matched readers: matched before anything below causes one.
  ASSERT_TRUE(errors.wait_matched() && unwinding.wait_matched()) << logs();
  ASSERT_TRUE(loom_results.subscribe(**dds, topic("loom_result"), QosKind::reply));

  // Status per feeder: the four feeders polled by SDO, decoded by the profile's tables.
  ASSERT_TRUE(status.wait_last(20s, [](const msg::FeederStatus& s) {
    if (!s.health().online() || s.health().nmt_state() != msg::NMT_OPERATIONAL || !s.feeder_count_read() ||
        s.feeder_count() != 4 || s.feeders().size() != 4) {
      return false;
    }
    for (const auto& f : s.feeders()) {
      if (!f.status_read() || !f.functions_read() || !f.error_condition_read()) return false;
    }
    return true;
  })) << logs();
  {
    const auto s = status.samples().back();
    for (std::size_t i = 0; i < 4; ++i) {
      const auto& f = s.feeders()[i];
      EXPECT_EQ(f.number(), i + 1);
      EXPECT_EQ(f.status().name(), "operational_mode");
      EXPECT_TRUE(f.status().valid());
      EXPECT_EQ(f.error_condition().name(), "no_error");
      EXPECT_EQ(f.functions().winding_direction().state(), "s");
      EXPECT_EQ(f.functions().yarn_break_sensor().state(), "active");
      EXPECT_FALSE(f.functions().brush_release().available());
      EXPECT_FALSE(f.in_error());
    }
    EXPECT_TRUE(s.control_box_error_read());
    EXPECT_EQ(s.control_box_error().name(), "no_error");
    EXPECT_FALSE(s.loom().seen()) << "no loom controller yet";
  }

  // Fault injection (simulator 2001h): feeder 2, yarn broken (04h) -> EMCY FF10h bitmap 2.
  auto sdo_write = SdoWriteClient::create(**dds, lb::ddsl::line_service_path("itest", "sdo_write"));  // line-wide
  ASSERT_TRUE(sdo_write);
  srv::SdoWrite_Request inject;
  inject.device("feeders");
  inject.index(0x2001);
  inject.sub_index(0);
  inject.value().data_type("UNSIGNED16");
  inject.value().unsigned_value(0x0402);
  auto injected = (*sdo_write)->call(inject, 10s);
  ASSERT_TRUE(injected) << injected.error().message;
  ASSERT_TRUE(injected->success()) << injected->message();
  ASSERT_TRUE(errors.wait(10s, [](const auto& v) { return !v.empty(); })) << logs();
  {
    const auto e = errors.samples().front();
    EXPECT_EQ(e.feeder(), 2);
    EXPECT_TRUE(e.in_error());
    EXPECT_EQ(e.bitmap(), 0x2u);
    EXPECT_TRUE(e.detail_read()) << e.remark();
    EXPECT_EQ(e.condition().name(), "yarn_broken");
    EXPECT_EQ(e.condition().raw(), 0x04);
  }
  ASSERT_TRUE(status.wait_last(5s, [](const msg::FeederStatus& s) {
    return s.error_bitmap() == 0x2 && s.feeders().size() == 4 && s.feeders()[1].in_error() &&
           !s.feeders()[0].in_error();
  })) << logs();
  ASSERT_TRUE(status.wait_last(5s,
                               [](const msg::FeederStatus& s) {
                                 return s.feeders().size() == 4 && s.feeders()[1].status().name() == "error_mode";
                               }))
      << "the next poll reads the feeder in error mode\n"
      << logs();

  // Feeder commands: invalid ones refused with the reason and never on CAN; reset clears the fault.
  auto commands = CommandClient::create(**dds, "itest/feeders/feeder_command");
  ASSERT_TRUE(commands);
  const auto unknown = command(**commands, 2, "fly");
  EXPECT_FALSE(unknown.success());
  EXPECT_NE(unknown.message().find("unknown feeder command"), std::string::npos) << unknown.message();
  const auto beyond = command(**commands, 9, "reset");
  EXPECT_FALSE(beyond.success());
  EXPECT_NE(beyond.message().find("reports 4"), std::string::npos) << beyond.message();
  EXPECT_EQ(sdo_downloads(spy, 0x600E), 0u) << "a refused command reached CAN";
  // The line-wide momentary-command service (saws, pullers, corrugators) refuses the feeder box:
  // its commands are the typed feeder services.
  auto press = PressClient::create(**dds, lb::ddsl::line_service_path("itest", "command"));
  ASSERT_TRUE(press);
  srv::Command_Request start;
  start.device("feeders");
  start.command("start");
  const auto pressed = (*press)->call(start, 10s);
  ASSERT_TRUE(pressed) << pressed.error().message;
  EXPECT_FALSE(pressed->success());
  EXPECT_NE(pressed->message().find("feeders (feeder, cia414-2@1.1) has no momentary commands"), std::string::npos)
      << pressed->message();
  const auto reset = command(**commands, 2, "reset");
  EXPECT_TRUE(reset.success()) << reset.message();
  EXPECT_EQ(reset.raw(), 0x04u);
  // This test's recorder reads the bus on a thread of its own: wait for the download it shows.
  EXPECT_TRUE(lb::test::eventually(10s, [&] { return sdo_downloads(spy, 0x600E) >= 1u; }));
  EXPECT_EQ(sdo_downloads(spy, 0x600E), 1u);
  ASSERT_TRUE(errors.wait(10s, [](const auto& v) { return v.size() >= 2; })) << logs();
  {
    const auto e = errors.samples()[1];
    EXPECT_EQ(e.feeder(), 2);
    EXPECT_FALSE(e.in_error());
    EXPECT_EQ(e.bitmap(), 0u);
    EXPECT_TRUE(e.detail_read());
    EXPECT_EQ(e.condition().name(), "no_error");
  }
  ASSERT_TRUE(status.wait_last(5s, [](const msg::FeederStatus& s) {
    return s.error_bitmap() == 0 && s.health().active_errors().empty() && s.feeders().size() == 4 &&
           !s.feeders()[1].in_error();
  })) << logs();

  // Function settings: read-modify-write; a function the feeder lacks is refused with the reason.
  auto functions = FunctionsClient::create(**dds, "itest/feeders/feeder_functions");
  ASSERT_TRUE(functions);
  srv::FeederFunctions_Request fr;
  fr.feeder(1);
  srv::FeederFunctionSetting setting;
  setting.function("tks_sensor");
  setting.state("active");
  fr.settings({setting});
  auto lacking = (*functions)->call(fr, 10s);
  ASSERT_TRUE(lacking) << lacking.error().message;
  EXPECT_FALSE(lacking->success());
  EXPECT_NE(lacking->message().find("not available"), std::string::npos) << lacking->message();
  setting.function("yarn_break_sensor");
  setting.state("not_active");
  fr.settings({setting});
  auto changed = (*functions)->call(fr, 10s);
  ASSERT_TRUE(changed) << changed.error().message;
  EXPECT_TRUE(changed->success()) << changed->message();
  ASSERT_TRUE(status.wait_last(5s, [](const msg::FeederStatus& s) {
    return s.feeders().size() == 4 && s.feeders()[0].functions().yarn_break_sensor().state() == "not_active";
  })) << logs();

  // The bridge as loom controller: start advice in RPDO2 (event-driven), then unwinding events.
  auto loom = (*dds)->writer<msg::LoomSetpointPubSubType>(topic("loom"), QosKind::command);
  ASSERT_TRUE(loom);
  ASSERT_TRUE(lb::test::eventually(10s, [&] {
    return loom->matched() > 0 && (*dds)->matched_writers(topic("loom_result")) > 0;
  })) << logs();
  msg::LoomSetpoint bad;
  bad.request_id(1);
  bad.pick_insertion({0x00, 0x07, 0xDD, 0xA3, 0x55});
  loom->write(bad);
  ASSERT_TRUE(loom_results.wait_last(5s, [](const msg::SetpointResult& r) { return r.request_id() == 1; })) << logs();
  EXPECT_FALSE(loom_results.samples().back().accepted());
  EXPECT_NE(loom_results.samples().back().reason().find("pick_insertion[2]"), std::string::npos);
  EXPECT_TRUE(spy.frames(0x200 + kNode).empty()) << "a refused pick insertion reached CAN";

  msg::LoomSetpoint run;
  run.request_id(2);
  run.loom_status("start_advice");
  run.maximum_speed_per_min(1000);
  run.loom_width_m(1.9);
  loom->write(run);
  ASSERT_TRUE(loom_results.wait_last(5s, [](const msg::SetpointResult& r) { return r.request_id() == 2; })) << logs();
  EXPECT_TRUE(loom_results.samples().back().accepted()) << loom_results.samples().back().reason();
  ASSERT_TRUE(unwinding.wait(10s, [](const auto& v) { return v.size() >= 5; })) << logs();
  const auto rpdo2 = spy.frames(0x300 + kNode);
  ASSERT_FALSE(rpdo2.empty());
  EXPECT_EQ(std::vector<std::uint8_t>(rpdo2.front().data.begin(), rpdo2.front().data.begin() + rpdo2.front().len),
            (std::vector<std::uint8_t>{0x01, 0xE8, 0x03, 0xBE, 0x00}));
  std::set<int> feeders;
  for (const auto& u : unwinding.samples()) {
    EXPECT_TRUE(u.in_range());
    EXPECT_GE(u.winding_number(), 1);
    EXPECT_GT(u.coil_unwinding_time_ms(), 0.0);
    feeders.insert(u.feeder_selected());
  }
  EXPECT_GE(feeders.size(), 2u) << "the feeders take turns";
  EXPECT_TRUE(status.wait_last(5s, [](const msg::FeederStatus& s) {
    return s.loom().seen() && s.loom().loom_status().name() == "start_advice";
  }));

  sdo_write->reset();  // service clients before the participant they live in
  commands->reset();
  press->reset();
  functions->reset();
  dds->reset();
  EXPECT_EQ(bridge.stop(), 0) << logs();
}

TEST(FeederLine, MonitorRoleDecodesLoomControllerAndNeverTransmits) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  lb::test::MonitoredLine line("fmon", 8, device_yaml("m"));
  auto& spy = line.spy();
  const auto logs = [&] { return line.logs(); };

  auto dds = lb::ddsl::Participant::create({8, true, "feeder-monitor-test"});
  ASSERT_TRUE(dds) << dds.error().message;
  const auto topic = [](const char* t) { return lb::ddsl::topic_name("fmon", "feeders", t); };
  lb::test::Collector<msg::FeederStatusPubSubType> status;
  lb::test::Collector<msg::FeederErrorPubSubType> errors;
  ASSERT_TRUE(status.subscribe(**dds, topic("status"), QosKind::state));
  ASSERT_TRUE(errors.subscribe(**dds, topic("feeder_error"), QosKind::event));
  lb::test::Collector<msg::DiagnosticsPubSubType> diag;
  ASSERT_TRUE(diag.subscribe(**dds, lb::ddsl::topic_name("fmon", "bridge", "diagnostics"), QosKind::state));
  ASSERT_TRUE(status.wait_last(10s, [](const msg::FeederStatus& s) { return s.health().online(); })) << logs();
  ASSERT_TRUE(errors.wait_matched()) << logs();  // an event reaches only a matched reader

  // The loom controller's RPDOs, built by hand (spec 4.2-4.5): start advice, 1000 1/min, 190 cm;
  // picks empty, single 7, single 16, double 10+3, reserved DDh; angle trigger.
  spy.clear();
  ASSERT_TRUE(spy.send(lb::can::make_frame(0x300 + kNode, {0x01, 0xE8, 0x03, 0xBE, 0x00})));
  ASSERT_TRUE(spy.send(lb::can::make_frame(0x200 + kNode, {0x00, 0x07, 0x10, 0xA3, 0xDD})));
  ASSERT_TRUE(spy.send(lb::can::make_frame(0x500 + kNode, {0x01})));
  ASSERT_TRUE(status.wait_last(10s, [](const msg::FeederStatus& s) {
    return s.loom().seen() && s.loom().pick_insertion().size() == 5 && s.loom().pick_insertion()[4].raw() == 0xDD &&
           s.loom().trigger_signal().name() == "angle_trigger";
  })) << logs();
  const auto l = status.samples().back().loom();
  EXPECT_EQ(l.loom_status().name(), "start_advice");
  EXPECT_EQ(l.maximum_speed_per_min(), 1000);
  EXPECT_DOUBLE_EQ(l.loom_width_m(), 1.9);
  EXPECT_EQ(l.pick_insertion()[1].kind(), "single_pick");
  EXPECT_EQ(l.pick_insertion()[2].colours().at(0), 16);
  EXPECT_EQ(l.pick_insertion()[3].kind(), "double_pick");
  EXPECT_FALSE(l.pick_insertion()[4].valid()) << "DDh is reserved";
  EXPECT_EQ(l.pick_insertion()[4].kind(), "");

  // An EMCY FF10h (feeder 3): an event, but the detail cannot be read without transmitting.
  ASSERT_TRUE(spy.send(lb::can::make_frame(0x080 + kNode, {0x10, 0xFF, 0x01, 0x04, 0x00, 0x00, 0x00, 0x00})));
  ASSERT_TRUE(errors.wait(10s, [](const auto& v) { return !v.empty(); })) << logs();
  EXPECT_EQ(errors.samples().front().feeder(), 3);
  EXPECT_TRUE(errors.samples().front().in_error());
  EXPECT_FALSE(errors.samples().front().detail_read());
  EXPECT_NE(errors.samples().front().remark().find("monitor role"), std::string::npos);

  // Commands are refused with the reason.
  srv::FeederCommand_Request reset;
  reset.feeder(1);
  reset.command("reset");
  ASSERT_NO_FATAL_FAILURE(
      lb::test::expect_refused_by_monitor<CommandClient>(**dds, "fmon/feeders/feeder_command", reset));

  // Over five more of the box's heartbeats, nothing but those heartbeats on the bus (the spy does
  // not hear its own frames).
  EXPECT_EQ(line.ids_after_heartbeats(kNode, 5), (std::set<std::uint32_t>{0x700u + kNode})) << logs();
  // The bridge never tried to transmit (its diagnostics after everything above).
  ASSERT_NO_FATAL_FAILURE(lb::test::expect_monitor_never_sent(diag, logs()));
  dds->reset();
  EXPECT_EQ(line.bridge().stop(), 0);
}

// A stop is never refused while the device is heard: feeder_command stop_mode (600Eh 03h) naming
// a run of the bridge that is not this one (a client's repeat after a restart) runs, as its own
// request; any other feeder command naming it is refused unrun, as every such request is.
TEST(FeederLine, AStopModeNamingAnEarlierBridgeRunRunsAndOtherCommandsAreRefused) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string tag = std::to_string(::getpid());
  const std::string bus = "virtual:it-feedstop-" + tag;
  const std::string tmp = ::testing::TempDir();
  const std::string cfg = tmp + "/feeder_stop_" + tag + ".yaml";
  std::ofstream(cfg) << "line: itest\ndds: {domain: 7, localhost_only: true}\nbuses:\n"
                        "  - {name: loom, interface: '" +
                            bus + "', role: master, sync_period_ms: 20}\n" + device_yaml("loom");

  lb::test::BusSpy spy(bus);
  lb::test::ChildProcess sim({LB_BIN_SIM, "--config", cfg}, tmp + "/feedstop_sim_" + tag + ".log");
  lb::test::ChildProcess bridge({LB_BIN_BRIDGE, "--config", cfg}, tmp + "/feedstop_bridge_" + tag + ".log");
  const auto logs = [&] { return "--- bridge ---\n" + bridge.log() + "--- sim ---\n" + sim.log(); };

  auto dds = lb::ddsl::Participant::create({7, true, "feeder-stop-test"});
  ASSERT_TRUE(dds) << dds.error().message;
  lb::test::Collector<msg::FeederStatusPubSubType> status;
  ASSERT_TRUE(status.subscribe(**dds, lb::ddsl::topic_name("itest", "feeders", "status"), QosKind::state));
  ASSERT_TRUE(status.wait_last(20s, [](const msg::FeederStatus& s) {
    return s.health().nmt_state() == msg::NMT_OPERATIONAL && s.feeders().size() == 4 && s.feeders()[0].status_read() &&
           s.feeders()[0].status().name() == "operational_mode";
  })) << logs();

  auto commands = CommandClient::create(**dds, "itest/feeders/feeder_command");
  ASSERT_TRUE(commands) << commands.error().message;
  // A run this bridge is not: 64 random bits make this one's own a 2^-64 chance.
  constexpr lb::ddsl::Incarnation kEarlierRun = 0x5EED'0000'0000'0001ULL;
  srv::FeederCommand_Request led;
  led.feeder(1);
  led.command("led_on");
  led.bridge_incarnation(kEarlierRun);
  const auto refused = (*commands)->ask(led, 10s);
  ASSERT_TRUE(refused) << refused.error().message;
  EXPECT_FALSE(refused->reply.success());
  EXPECT_TRUE(refused->bridge_restarted()) << refused->reply.message();
  EXPECT_EQ(sdo_downloads(spy, 0x600E), 0u) << "a command meant for an earlier run reached CAN";

  srv::FeederCommand_Request stop;
  stop.feeder(1);
  stop.command("stop_mode");
  stop.bridge_incarnation(kEarlierRun);
  const auto stopped = (*commands)->ask(stop, 10s);
  ASSERT_TRUE(stopped) << stopped.error().message;
  EXPECT_TRUE(stopped->reply.success()) << "the stop was refused: " << stopped->reply.message();
  EXPECT_FALSE(stopped->bridge_restarted());
  EXPECT_EQ(stopped->reply.raw(), 0x03u) << "CiA 414-2 600Eh: stop mode is 03h";
  // The answer came once the download was on the bus; this test's recorder reads it on a thread of
  // its own, which a loaded machine may run a little later.
  EXPECT_TRUE(lb::test::eventually(10s, [&] { return sdo_downloads(spy, 0x600E) >= 1u; }));
  EXPECT_EQ(sdo_downloads(spy, 0x600E), 1u);
  EXPECT_TRUE(status.wait_last(10s,
                               [](const msg::FeederStatus& s) {
                                 return s.feeders().size() == 4 &&
                                        s.feeders()[0].status().name() == "non_operational_mode";
                               }))
      << "the box never reported feeder 1 out of operation\n"
      << logs();
}

// After a power cut of the box alone, the feeders do not run again by themselves (IEC 60204-1):
// the bridge, which played the loom controller with start advice, sends the restarted box its loom
// status as stop (CiA 414-2 600Ah 00h), never start advice, until the loom (an operator) says so.
// RPDO2 (300h + 10, event-driven) carries 600Ah (UNSIGNED8) and 6004h (UNSIGNED32: bits 0-15 the
// maximum speed 600 1/min = 0258h, bits 16-31 the loom width 190 cm = 00BEh).
TEST(FeederLine, ABoxThatLostPowerIsNotToldToRunAgain) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string tag = std::to_string(::getpid());
  const std::string bus = "virtual:it-feedpower-" + tag;
  const std::string tmp = ::testing::TempDir();
  const std::string cfg = tmp + "/feeder_power_" + tag + ".yaml";
  std::ofstream(cfg) << "line: itest\ndds: {domain: 8, localhost_only: true}\nbuses:\n"
                        "  - {name: loom, interface: '" +
                            bus + "', role: master, sync_period_ms: 20}\n" + device_yaml("loom");

  lb::test::BusSpy spy(bus);
  auto sim = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", cfg},
                                                      tmp + "/feedpower_sim_" + tag + ".log");
  lb::test::ChildProcess bridge({LB_BIN_BRIDGE, "--config", cfg}, tmp + "/feedpower_bridge_" + tag + ".log");
  const auto logs = [&] { return "--- bridge ---\n" + bridge.log() + "--- sim ---\n" + sim->log(); };

  auto dds = lb::ddsl::Participant::create({8, true, "feeder-power-test"});
  ASSERT_TRUE(dds) << dds.error().message;
  lb::test::Collector<msg::FeederStatusPubSubType> status;
  lb::test::Collector<msg::SetpointResultPubSubType> loom_results;
  ASSERT_TRUE(status.subscribe(**dds, lb::ddsl::topic_name("itest", "feeders", "status"), QosKind::state));
  ASSERT_TRUE(loom_results.subscribe(**dds, lb::ddsl::topic_name("itest", "feeders", "loom_result"), QosKind::reply));
  ASSERT_TRUE(status.wait_last(20s, [](const msg::FeederStatus& s) {
    return s.health().nmt_state() == msg::NMT_OPERATIONAL;
  })) << logs();
  auto loom = (*dds)->writer<msg::LoomSetpointPubSubType>(lb::ddsl::topic_name("itest", "feeders", "loom"),
                                                          QosKind::command);
  ASSERT_TRUE(loom);
  ASSERT_TRUE(lb::test::eventually(10s, [&] {
    return loom->matched() > 0 && (*dds)->matched_writers(lb::ddsl::topic_name("itest", "feeders", "loom_result")) > 0;
  })) << logs();
  msg::LoomSetpoint run;
  run.request_id(1);
  run.loom_status("start_advice");
  run.maximum_speed_per_min(600);
  run.loom_width_m(1.9);
  loom->write(run);
  ASSERT_TRUE(loom_results.wait_last(5s, [](const msg::SetpointResult& r) { return r.request_id() == 1; })) << logs();
  ASSERT_TRUE(loom_results.samples().back().accepted()) << loom_results.samples().back().reason();
  const auto payload = [](const lb::can::CanFrame& f) {
    return std::vector<std::uint8_t>(f.data.begin(), f.data.begin() + f.len);
  };
  ASSERT_TRUE(spy.wait_until([&](const std::vector<lb::can::CanFrame>& frames) {
    return std::any_of(frames.begin(), frames.end(), [&](const auto& f) {
      return f.id == 0x300 + kNode && payload(f) == std::vector<std::uint8_t>{0x01, 0x58, 0x02, 0xBE, 0x00};
    });
  })) << "start advice never reached the box\n"
      << logs();

  // The box alone loses power (the bridge keeps running) and comes back.
  ::kill(sim->pid(), SIGKILL);
  sim.reset();
  spy.clear();
  sim = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", cfg},
                                                 tmp + "/feedpower_sim2_" + tag + ".log");
  // Its boot-up, then the bridge's NMT start (000h: 01h, node 10), then its loom status again.
  ASSERT_TRUE(spy.wait_until([&](const std::vector<lb::can::CanFrame>& frames) {
    const auto start = std::find_if(frames.begin(), frames.end(), [](const auto& f) {
      return f.id == 0x000 && f.len == 2 && f.data[0] == 0x01 && f.data[1] == kNode;
    });
    return start != frames.end() &&
           std::any_of(start, frames.end(), [](const auto& f) { return f.id == 0x300 + kNode; });
  })) << "the restarted box was never started and sent its loom status\n"
      << logs();
  ASSERT_TRUE(status.wait_last(10s, [](const msg::FeederStatus& s) {
    return s.health().nmt_state() == msg::NMT_OPERATIONAL;
  })) << logs();
  for (const auto& f : spy.frames(0x300 + kNode)) {
    ASSERT_GE(f.len, 1);
    EXPECT_EQ(f.data[0], 0x00) << "600Ah is not stop after the box's power cut: the feeders were told to run";
  }
  // The maximum speed and the loom width in force stay (they enable nothing).
  const auto after = spy.frames(0x300 + kNode);
  ASSERT_FALSE(after.empty());
  EXPECT_EQ(payload(after.front()), (std::vector<std::uint8_t>{0x00, 0x58, 0x02, 0xBE, 0x00}));
  // An operator's start advice runs them again.
  run.request_id(2);
  loom->write(run);
  ASSERT_TRUE(loom_results.wait_last(5s, [](const msg::SetpointResult& r) { return r.request_id() == 2; })) << logs();
  EXPECT_TRUE(loom_results.samples().back().accepted()) << loom_results.samples().back().reason();
  EXPECT_TRUE(spy.wait_until([&](const std::vector<lb::can::CanFrame>& frames) {
    return std::any_of(frames.begin(), frames.end(),
                       [&](const auto& f) { return f.id == 0x300 + kNode && f.data[0] == 0x01; });
  })) << logs();
  dds->reset();
  EXPECT_EQ(bridge.stop(), 0) << logs();
}
