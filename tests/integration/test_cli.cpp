// linebridge-cli for every device type, as an integrator uses it: the real CLI process against
// the real bridge and simulator. Readable status of pullers, corrugators and feeder boxes (names,
// not numbers), their set values, a feeder box's topics and typed services, exit codes that tell
// "refused" (1) from "no answer" (3), and the line file from LINEBRIDGE_CONFIG or --config
// anywhere on the command line; an echo whose pipe closes ends cleanly.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>
#include <thread>

#include "app/boot_wait.hpp"
#include "app/common_text.hpp"
#include "app/saw_text.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/corrugatorPubSubTypes.h"
#include "msgs/feederPubSubTypes.h"
#include "msgs/pullerPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/collector.hpp"
#include "support/line_harness.hpp"
#include "support/line_views.hpp"
#include "support/run_command.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using lb::ddsl::QosKind;
using lb::test::operational;

namespace {

struct CliRun {
  int exit_code;
  std::string output;  // stdout and stderr
};

int runs = 0;

CliRun run_cli(std::vector<std::string> args, std::chrono::seconds limit = 20s) {
  args.insert(args.begin(), LB_BIN_CLI);
  lb::test::ChildProcess p(args, ::testing::TempDir() + "/cli_" + std::to_string(::getpid()) + "_" +
                                     std::to_string(++runs) + ".log");
  lb::test::eventually(limit, [&p] { return !p.running(); });  // else stopped below, and its exit code says so
  const int status = p.stop();
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, p.log()};
}

bool has(const CliRun& r, const std::string& text) { return r.output.find(text) != std::string::npos; }

std::string last_text(lb::test::Collector<msg::DiagnosticsPubSubType>& diag) {
  const auto all = diag.samples();
  return all.empty() ? std::string("no diagnostics\n") : lb::app::to_text(all.back());
}

class Cli : public ::testing::Test {
 protected:
  void SetUp() override {
    line_ = std::make_unique<lb::test::LineHarness>("clitest", 33);
    line_->start("  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n"
                 "  - {name: puller1, bus: b, node_id: 6, profile: cia420-2, version: '1.0'}\n"
                 "  - {name: corr1, bus: b, node_id: 7, profile: cia420-3, version: '3.1'}\n"
                 "  - {name: puller3, bus: b, node_id: 8, profile: cia420-2, version: '3.0-status'}\n"
                 "  - {name: box1, bus: b, node_id: 10, profile: cia414-2, version: '1.1'}\n");
    config_ = ::testing::TempDir() + "/clitest_bridge_" + std::to_string(::getpid()) + ".yaml";
    ASSERT_TRUE(puller_.subscribe(line_->dds(), line_->topic("puller1", "status"), QosKind::state));
    ASSERT_TRUE(corr_.subscribe(line_->dds(), line_->topic("corr1", "status"), QosKind::state));
    ASSERT_TRUE(box_.subscribe(line_->dds(), line_->topic("box1", "status"), QosKind::state));
    ASSERT_TRUE(puller_.wait_last(30s, operational<msg::PullerStatus>)) << line_->logs();
    ASSERT_TRUE(corr_.wait_last(30s, operational<msg::CorrugatorStatus>)) << line_->logs();
    ASSERT_TRUE(box_.wait_last(30s, [](const msg::FeederStatus& s) { return operational(s) && s.feeder_count_read(); }))
        << line_->logs();
  }
  CliRun cli(std::vector<std::string> args, std::chrono::seconds limit = 20s) {
    args.insert(args.begin(), {"--config", config_});
    return run_cli(std::move(args), limit);
  }

  std::unique_ptr<lb::test::LineHarness> line_;
  std::string config_;
  lb::test::Collector<msg::PullerStatusPubSubType> puller_;
  lb::test::Collector<msg::CorrugatorStatusPubSubType> corr_;
  lb::test::Collector<msg::FeederStatusPubSubType> box_;
};

}  // namespace

TEST_F(Cli, EchoShowsEveryDeviceTypeReadablyWithNames) {
  const auto puller = cli({"echo", "puller1", "status", "--duration", "2"});
  EXPECT_EQ(puller.exit_code, 0) << puller.output;
  EXPECT_TRUE(has(puller, "puller1 ")) << puller.output;
  EXPECT_TRUE(has(puller, "operational     online")) << puller.output;
  EXPECT_TRUE(has(puller, "| set: extruder stopped, speed 0.00 %")) << puller.output;
  // Status bits by their IDL names, the word's set bits each named (CiA 420-2 6030h: bit 1 ready
  // to start, bits 9/11/13 functions f1..f3 ready).
  EXPECT_TRUE(has(puller, "status 2A02h [motor_ready_to_start f1_ready f2_ready f3_ready]")) << "status bits by name\n"
                                                                                             << puller.output;
  const auto puller3 = cli({"echo", "puller3", "--duration", "2"});
  // Bit 15 set: the speed set value comes from remote, a code field by its profile name.
  EXPECT_TRUE(has(puller3, "status AA02h [motor_ready_to_start f1_ready f2_ready f3_ready speed_set_mode=remote]"))
      << "an enumeration by name\n"
      << puller3.output;
  const auto corr = cli({"echo", "corr1", "status", "--duration", "2"});
  EXPECT_EQ(corr.exit_code, 0) << corr.output;
  // Status bits by name: the idle corrugator is ready (6030h bit 1); master_extruder_enabled
  // (bit 7) is not expected here, the simulated drive sets it only while running.
  EXPECT_TRUE(has(corr, "corr1 ") && has(corr, "status 2A02h [drive_ready_to_start f1_ready f2_ready f3_ready]"))
      << corr.output;
  const auto box = cli({"echo", "box1", "status", "--duration", "3"});
  EXPECT_EQ(box.exit_code, 0) << box.output;
  EXPECT_TRUE(has(box, "4 feeder(s)")) << box.output;
  EXPECT_TRUE(has(box, "feeder   1: operational_mode | condition no_error")) << "codes by name\n" << box.output;
  EXPECT_TRUE(has(box, "yarn-break active")) << box.output;
  const auto wrong = cli({"echo", "puller1", "cut", "--duration", "1"});
  EXPECT_EQ(wrong.exit_code, 2) << wrong.output;
  EXPECT_TRUE(has(wrong, "a puller has no topic 'cut' (status, setpoint_result, info, emergency)")) << wrong.output;
}

TEST_F(Cli, EchoIntoAPipeThatClosesEndsCleanlyAndTheNextClientIsAnswered) {
  // `linebridge-cli echo ... | head -n 1`: once head has its line and is gone, the echo must end
  // by itself with exit 0 (not be killed by SIGPIPE: its DDS participant would stay matched to the
  // bridge's writers until its lease ran out), and the next client is answered at once.
  const auto piped = lb::test::run_command({"/bin/bash", "-c",
                                            "set -o pipefail; \"$0\" --config \"$1\" echo saw1 status | head -n 1",
                                            LB_BIN_CLI, config_},
                                           20s);
  EXPECT_EQ(piped.exit_code, 0) << "the echo's exit status through the pipe (141: killed by SIGPIPE)\n" << piped.output;
  EXPECT_TRUE(has({piped.exit_code, piped.output}, "saw1 ")) << piped.output;
  const auto next = cli({"set", "saw1", "--program", "on", "--sync-speed-percent", "50", "--product-length-m", "1.0"},
                        10s);
  EXPECT_EQ(next.exit_code, 0) << next.output << line_->logs();
  EXPECT_TRUE(has(next, "accepted")) << next.output;
}

TEST_F(Cli, SetTakesEachDevicesSetValues) {
  auto r = cli({"set", "puller1", "--extruder", "running", "--speed-percent", "25"});
  EXPECT_EQ(r.exit_code, 0) << r.output << line_->logs();
  EXPECT_TRUE(has(r, "puller1: accepted: extruder running, speed 25 %")) << r.output;
  EXPECT_TRUE(puller_.wait_last(5s, [](const msg::PullerStatus& s) {
    return s.control_word().extruder_running() && std::abs(s.speed_set_percent() - 25.0) < 1e-9;
  }));
  r = cli({"set", "corr1", "--speed-percent", "-10"});  // extruder not given: stays as in force
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(corr_.wait_last(5s, [](const msg::CorrugatorStatus& s) {
    return std::abs(s.speed_set_percent() + 10.0) < 1e-9;
  }));
  r = cli({"set", "puller1", "--speed-percent", "120"});
  EXPECT_EQ(r.exit_code, 1) << "refused by the bridge\n" << r.output;
  EXPECT_TRUE(has(r, "set value refused")) << r.output;
  r = cli({"set", "puller1", "--sync-speed-percent", "10"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(has(r, "--sync-speed-percent is not a set value of a puller (--extruder, --speed-percent)")) << r.output;
  r = cli({"set", "saw1", "--wall-thickening", "on", "--program", "on", "--sync-speed-percent", "50",
           "--product-length-m", "1.0"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "wall-thickening on")) << r.output;
  // The new length flipped the saw's change-of-length toggle (CiA 420-4 6020h bit 2): shown as a
  // toggle with its level, never as a button pressed.
  const auto saw = cli({"echo", "saw1", "status", "--duration", "2"});
  EXPECT_TRUE(has(saw, ", toggles [change_of_length=1]")) << saw.output;
  EXPECT_FALSE(has(saw, "pressed")) << saw.output;
  r = cli({"press", "puller1", "motor_start"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "motor_start: on the bus in ")) << r.output;
}

// A fresh bridge has no set value in force (the status reports them all 0): a value not given would
// be a 0 nobody chose (a 0 m length), so `set` names the values to give and sends nothing (exit 2).
// A stop needs none; once values are in force, those not given keep theirs.
TEST_F(Cli, SetWithNothingInForceNamesTheValuesToGiveAndSendsNothing) {
  lb::test::Collector<msg::SawStatusPubSubType> saw;
  lb::test::Collector<msg::SawSetpointPubSubType> sent;  // every set value any client writes
  ASSERT_TRUE(saw.subscribe(line_->dds(), line_->topic("saw1", "status"), QosKind::state));
  ASSERT_TRUE(sent.subscribe(line_->dds(), line_->topic("saw1", "setpoint"), QosKind::command));
  ASSERT_TRUE(saw.wait_last(30s, [](const msg::SawStatus& s) {
    return operational(s) && s.control_word().raw() == 0 && s.sync_speed_set_percent() == 0 &&
           s.product_length_set_m() == 0;
  })) << "a fresh saw reports no set value in force";

  auto r = cli({"set", "saw1", "--program", "on", "--sync-speed-percent", "90"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(has(r, "saw1: no set values in force yet (its status reports them all 0: none was given since the "
                     "bridge started and none was kept from before), so the values not given have nothing to keep: "
                     "give --product-length-m too (nothing was sent)"))
      << r.output;
  EXPECT_FALSE(has(r, "accepted")) << r.output;
  r = cli({"set", "saw1", "--wall-thickening", "on"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(has(r, "give --sync-speed-percent, --product-length-m too")) << r.output;
  r = cli({"set", "puller1", "--extruder", "running"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(has(r, "puller1: no set values in force yet") && has(r, "give --speed-percent too")) << r.output;
  r = cli({"set", "box1", "--loom-status", "start_advice"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(has(r, "give --maximum-speed, --loom-width-m too")) << r.output;

  // A stop carries nothing that runs: sent.
  r = cli({"set", "saw1", "--program", "off"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "saw1: accepted: program off")) << r.output;
  r = cli({"set", "saw1", "--program", "on", "--sync-speed-percent", "90", "--product-length-m", "1.2"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "saw1: accepted: program on, wall-thickening off, smooth pipe, sync speed 90 %, product length "
                     "1.2 m"))
      << r.output;
  // Every set value the clients wrote has come (the last one accepted marks it): the refused ones
  // are not among them, only the stop and the full one.
  ASSERT_TRUE(sent.wait(10s, [](const auto& v) { return !v.empty() && v.back().product_length_m() == 1.2; }));
  for (const auto& sp : sent.samples()) {
    EXPECT_TRUE(!sp.saw_program_on() || sp.product_length_m() == 1.2)
        << "a set value that switched the program on at " << sp.product_length_m() << " m went out";
  }
  // In force now: a value not given keeps its own.
  r = cli({"set", "saw1", "--sync-speed-percent", "80"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "sync speed 80 %, product length 1.2 m")) << r.output;
}

TEST_F(Cli, FeederTopicsServicesAndLoomPlay) {
  // The loom runs: the box sends an unwinding event per winding.
  // The echoes run until what the commands below cause has come (or 60 s): a fixed duration was
  // too short under ThreadSanitizer, where each of those commands takes seconds.
  lb::test::ChildProcess unwinding({LB_BIN_CLI, "echo", "box1", "unwinding", "--config", config_, "--duration", "60"},
                                   ::testing::TempDir() + "/cli_unwinding_" + std::to_string(::getpid()) + ".log");
  lb::test::ChildProcess errors({LB_BIN_CLI, "echo", "box1", "feeder_error", "--config", config_, "--duration", "60"},
                                ::testing::TempDir() + "/cli_feeder_error_" + std::to_string(::getpid()) + ".log");
  // Both echoes subscribed before anything below causes an event: a writer of this test on each
  // topic (it never writes) is matched with their readers once discovery has announced them, the
  // same discovery that matches them with the bridge's writers.
  auto unwinding_probe = line_->dds().writer<msg::FeederUnwindingPubSubType>(line_->topic("box1", "unwinding"),
                                                                             QosKind::event);
  auto errors_probe = line_->dds().writer<msg::FeederErrorPubSubType>(line_->topic("box1", "feeder_error"),
                                                                      QosKind::event);
  ASSERT_TRUE(unwinding_probe && errors_probe);
  ASSERT_TRUE(lb::test::eventually(60s, [&] { return unwinding_probe->matched() > 0 && errors_probe->matched() > 0; }))
      << "the echoes never subscribed\n"
      << unwinding.log() << errors.log();
  auto r = cli({"set", "box1", "--loom-status", "start_advice", "--maximum-speed", "600", "--loom-width-m", "1.9"});
  EXPECT_EQ(r.exit_code, 0) << r.output << line_->logs();
  EXPECT_TRUE(has(r, "loom start_advice at 600 1/min, width 1.9 m")) << r.output;
  r = cli({"feeder-command", "box1", "2", "led_on"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "feeder 2 led_on written (5h)")) << r.output;
  r = cli({"feeder-command", "box1", "2", "fly"});
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(has(r, "refused: unknown feeder command 'fly'")) << r.output;
  r = cli({"feeder-functions", "box1", "1", "yarn_break_sensor=not_active"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  // Feeder 2, yarn broken (6007h 04h), through the simulator's fault injection 2001h.
  r = cli({"sdo-write", "box1", "0x2001", "0", "UNSIGNED16", "0x0402"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = cli({"weft-insertion-type", "box1", "air_jet"});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = cli({"press", "box1", "manual_cut"});
  EXPECT_EQ(r.exit_code, 1) << r.output;  // a box has no momentary commands: refused by the bridge
  r = cli({"feeder-command", "puller1", "1", "reset"});
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_TRUE(errors.wait_log("FEEDER 2 IN ERROR (bitmap 00000002h): yarn_broken", 20s)) << errors.log();
  EXPECT_TRUE(unwinding.wait_log("UNWINDING feeder ", 10s)) << unwinding.log();
  EXPECT_NE(unwinding.log().find("box1 "), std::string::npos);
  EXPECT_EQ(unwinding.stop(), 0);  // SIGTERM: an echo ends cleanly
  EXPECT_EQ(errors.stop(), 0);
}

TEST_F(Cli, LineFileFromTheEnvironmentOrAnywhereOnTheCommandLine) {
  ::setenv("LINEBRIDGE_CONFIG", config_.c_str(), 1);
  auto r = run_cli({"list"});
  ::unsetenv("LINEBRIDGE_CONFIG");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "device box1 on b node 10: feeder cia414-2@1.1")) << r.output;
  r = run_cli({"get", "puller1", "configuration_word", "--config", config_});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "configuration_word = 1")) << r.output;
}

// An operator's `nmt ... pre-operational` takes the device out of operational: the bridge's
// diagnostics then say what holds it, not the boot's last step ("started"); `nmt start` gives
// "started" back.
TEST_F(Cli, DiagnosticsFollowAnOperatorsNmtPreOperationalAndStart) {
  lb::test::Collector<msg::DiagnosticsPubSubType> diag;
  ASSERT_TRUE(diag.subscribe(line_->dds(), line_->topic("bridge", "diagnostics"), QosKind::state));
  const auto puller_node = [](const msg::Diagnostics& d) -> const msg::NodeDiagnostics* {
    for (const auto& n : d.nodes()) {
      if (n.device() == "puller1") return &n;
    }
    return nullptr;
  };
  auto r = cli({"nmt", "puller1", "pre-operational"});
  ASSERT_EQ(r.exit_code, 0) << r.output << line_->logs();
  EXPECT_TRUE(diag.wait_last(30s,
                             [&](const msg::Diagnostics& d) {
                               const auto* n = puller_node(d);
                               return n != nullptr && n->node_state() == "stopped by operator" &&
                                      n->boot_state() != "started" &&
                                      n->boot_state().find("pre-operational") != std::string::npos;
                             }))
      << last_text(diag) << line_->logs();
  EXPECT_TRUE(puller_.wait_last(10s, [](const msg::PullerStatus& s) {
    return s.health().nmt_state() == msg::NMT_PRE_OPERATIONAL;
  }));
  r = cli({"nmt", "puller1", "start"});
  ASSERT_EQ(r.exit_code, 0) << r.output << line_->logs();
  EXPECT_TRUE(diag.wait_last(30s,
                             [&](const msg::Diagnostics& d) {
                               const auto* n = puller_node(d);
                               return n != nullptr && n->node_state() == "operational" && n->boot_state() == "started";
                             }))
      << last_text(diag) << line_->logs();
}

// NMT to a device the bridge does not hear (its simulator frozen): the command is sent, so the
// CLI says sent and exits 0, with what is not known yet; the device, running again, takes the
// reset (its boot-up, counted in the bridge's diagnostics).
TEST_F(Cli, NmtToADeviceNotHeardIsSentAndSaysSo) {
  lb::test::Collector<msg::SawStatusPubSubType> saw;
  lb::test::Collector<msg::DiagnosticsPubSubType> diag;
  ASSERT_TRUE(saw.subscribe(line_->dds(), line_->topic("saw1", "status"), QosKind::state));
  ASSERT_TRUE(diag.subscribe(line_->dds(), line_->topic("bridge", "diagnostics"), QosKind::state));
  const auto saw_boot_ups = [](const msg::Diagnostics& d) -> std::int64_t {
    for (const auto& n : d.nodes()) {
      if (n.device() == "saw1") return n.boot_ups();
    }
    return -1;
  };
  // Its boot-ups so far (the simulator's power-on one, if the bridge heard it): the reset's comes on top.
  ASSERT_TRUE(saw.wait_last(30s, operational<msg::SawStatus>)) << line_->logs();
  ASSERT_TRUE(diag.wait_last(30s, [&](const msg::Diagnostics& d) { return saw_boot_ups(d) >= 0; })) << last_text(diag);
  const auto boot_ups_before = saw_boot_ups(diag.samples().back());
  const auto sim = line_->sim().pid();
  ASSERT_EQ(::kill(sim, SIGSTOP), 0);
  struct Resume {
    pid_t pid;
    ~Resume() { ::kill(pid, SIGCONT); }
  } resume{sim};
  ASSERT_TRUE(saw.wait_last(30s, [](const msg::SawStatus& s) { return !s.health().online(); }))
      << "a frozen saw still shown online\n"
      << line_->logs();
  const auto r = cli({"nmt", "saw1", "reset-node"});
  EXPECT_EQ(r.exit_code, 0) << r.output << line_->logs();
  EXPECT_TRUE(has(r, "NMT reset-node sent; saw1 was not heard before (no heartbeat within its timeout): its boot-up "
                     "will tell that it took effect"))
      << r.output;
  EXPECT_FALSE(has(r, "refused")) << r.output;
  ASSERT_EQ(::kill(sim, SIGCONT), 0);
  EXPECT_TRUE(diag.wait_last(30s, [&](const msg::Diagnostics& d) { return saw_boot_ups(d) > boot_ups_before; }))
      << "the reset sent did not reach the saw\n"
      << last_text(diag) << line_->logs();
}

// When `set` may send: once the bridge's diagnostics say the device's boot passed, or settled
// where the bridge's answer says why; never while it is still booting.
TEST(CliText, SetWaitsForTheBootToPassOrSettle) {
  const auto node = [](const char* node_state, const char* boot_state) {
    msg::NodeDiagnostics n;
    n.node_state(node_state);
    n.boot_state(boot_state);
    return n;
  };
  EXPECT_FALSE(lb::app::boot_settled(node("booting", "writing the configuration (3 writes)")));
  EXPECT_FALSE(lb::app::boot_settled(node("unknown", "reading device type and identity")));
  EXPECT_FALSE(lb::app::boot_settled(node("resetting", "reset: waiting for its boot-up")));
  EXPECT_FALSE(lb::app::boot_settled(node("lost", "waiting for its heartbeat")));
  EXPECT_FALSE(lb::app::boot_settled(node("", "")));
  EXPECT_TRUE(lb::app::boot_settled(node("booting", "started")));  // passed; operational at its next heartbeat
  EXPECT_TRUE(lb::app::boot_settled(node("operational", "started")));
  EXPECT_TRUE(lb::app::boot_settled(
      node("stopped by operator", "configured; kept pre-operational by the operator (nmt start releases it)")));
  EXPECT_TRUE(lb::app::boot_settled(node("boot failed", "failed (D): identity; next try in 1000 ms")));
  EXPECT_TRUE(lb::app::boot_settled(node("monitored", "monitored")));
}

// Nobody answers: exit 3, not the exit code of a refusal; echo says it waits for a bridge.
TEST(CliWithoutBridge, NoAnswerIsExitThreeAndEchoSaysItWaits) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string config = ::testing::TempDir() + "/cli_nobridge_" + std::to_string(::getpid()) + ".yaml";
  std::ofstream(config) << "line: nobody\ndds: {domain: 34}\nbuses:\n  - {name: b, interface: 'virtual:nobody'}\n"
                           "devices:\n  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n";
  auto r = run_cli({"press", "saw1", "manual_cut", "--timeout", "2", "--config", config});
  EXPECT_EQ(r.exit_code, 3) << r.output;
  EXPECT_TRUE(has(r, "no answer: ")) << r.output;
  r = run_cli({"set", "saw1", "--program", "on", "--timeout", "2", "--config", config});
  EXPECT_EQ(r.exit_code, 3) << r.output;
  r = run_cli({"echo", "saw1", "--duration", "5", "--config", config});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "waiting for the bridge: nothing publishes rt/nobody/saw1/status")) << r.output;
}

// An answer lost on its way to the CLI (Fast DDS 2.9.1 can lose a writer's last sample after a
// burst; README "Requests written faster than read"): `set` asks again with the same request id
// until answered. No bridge can be made to lose an answer on demand, so a responder on the bridge's
// topics stands in for one whose first answer was lost: it publishes the saw's status (online) and
// answers a set value only when the same request comes a second time.
TEST(CliWithoutBridge, SetAsksAgainUntilAnswered) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string config = ::testing::TempDir() + "/cli_askagain_" + std::to_string(::getpid()) + ".yaml";
  std::ofstream(config) << "line: askagain\ndds: {domain: 35}\nbuses:\n  - {name: b, interface: 'virtual:askagain'}\n"
                           "devices:\n  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n";
  // What the callback reaches is declared before the participant, so it outlives the callbacks.
  std::mutex m;
  std::map<std::uint64_t, int> seen;  // request id -> times it came
  double speed = 0;
  double length = 0;
  lb::ddsl::Writer<msg::SetpointResultPubSubType> answers;
  auto dds = lb::ddsl::Participant::create({35, true, "askagain-responder"});
  ASSERT_TRUE(dds) << dds.error().message;
  auto& p = **dds;
  auto status = p.writer<msg::SawStatusPubSubType>(lb::ddsl::topic_name("askagain", "saw1", "status"), QosKind::state);
  auto results = p.writer<msg::SetpointResultPubSubType>(lb::ddsl::topic_name("askagain", "saw1", "setpoint_result"),
                                                         QosKind::reply);
  ASSERT_TRUE(status && results);
  answers = *results;
  ASSERT_TRUE(p.subscribe<msg::SawSetpointPubSubType>(lb::ddsl::topic_name("askagain", "saw1", "setpoint"),
                                                      QosKind::command, [&](const msg::SawSetpoint& sp, const auto&) {
                                                        int times = 0;
                                                        {
                                                          std::lock_guard lock(m);
                                                          times = ++seen[sp.request_id()];
                                                          speed = sp.sync_speed_percent();
                                                          length = sp.product_length_m();
                                                        }
                                                        if (times < 2) return;  // the first answer "lost"
                                                        msg::SetpointResult r;
                                                        r.request_id(sp.request_id());
                                                        r.accepted(true);
                                                        answers.write(r);
                                                      }));
  msg::SawStatus online;
  online.health().online(true);
  online.health().nmt_state(msg::NMT_OPERATIONAL);
  online.product_length_set_m(1.0);  // a set value in force, which the fields not given keep
  ASSERT_TRUE(status->write(online));
  // Like a bridge, it says in its diagnostics that the saw's boot passed (set waits for that).
  auto diagnostics = p.writer<msg::DiagnosticsPubSubType>(lb::ddsl::topic_name("askagain", "bridge", "diagnostics"),
                                                          QosKind::state);
  ASSERT_TRUE(diagnostics);
  msg::Diagnostics d;
  d.line("askagain");
  msg::NodeDiagnostics n;
  n.device("saw1");
  n.online(true);
  n.node_state("operational");
  n.boot_state("started");
  d.nodes().push_back(n);
  ASSERT_TRUE(diagnostics->write(d));

  const auto r = run_cli({"set", "saw1", "--sync-speed-percent", "40", "--timeout", "8", "--config", config});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "saw1: accepted: ")) << r.output;
  std::lock_guard lock(m);
  ASSERT_EQ(seen.size(), 1u) << "every write of one set value carries its request id";
  EXPECT_EQ(seen.begin()->second, 2) << "asked again once, after the first answer did not come";
  EXPECT_DOUBLE_EQ(speed, 40.0);
  EXPECT_DOUBLE_EQ(length, 1.0);
}

// The same for a service call: `press` (and every other service call) asks again every second,
// naming its first request by sample identity, so the bridge answers the repeat from its first
// answer instead of pressing twice (tests/integration/test_service_repeat.cpp shows that side).
// The responder stands in for a bridge whose first answer was lost: it answers only a repeat,
// and answers it as the bridge does, to the first request. Like a bridge, it publishes its run in
// its diagnostics; the first request and the repeat name that run.
TEST(CliWithoutBridge, ServiceCallAsksAgainNamingTheFirstRequest) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const std::string config = ::testing::TempDir() + "/cli_askagain_svc_" + std::to_string(::getpid()) + ".yaml";
  std::ofstream(config)
      << "line: askagainsvc\ndds: {domain: 37}\nbuses:\n  - {name: b, interface: 'virtual:askagainsvc'}\n"
         "devices:\n  - {name: saw1, bus: b, node_id: 3, profile: cia420-4, version: '3.1'}\n";
  using eprosima::fastrtps::rtps::SampleIdentity;
  struct Seen {
    SampleIdentity self, related;
    std::string device, command;
    lb::ddsl::Incarnation run;
  };
  std::mutex m;
  std::vector<Seen> seen;
  lb::ddsl::Writer<srv::Command_ResponsePubSubType> answers;
  auto dds = lb::ddsl::Participant::create({37, true, "askagain-service-responder"});
  ASSERT_TRUE(dds) << dds.error().message;
  auto& p = **dds;
  const auto path = lb::ddsl::line_service_path("askagainsvc", "command");
  auto replies = p.writer<srv::Command_ResponsePubSubType>(lb::ddsl::reply_topic(path), QosKind::reply);
  ASSERT_TRUE(replies);
  answers = *replies;
  auto diagnostics = p.writer<msg::DiagnosticsPubSubType>(lb::ddsl::topic_name("askagainsvc", "bridge", "diagnostics"),
                                                          QosKind::state);
  ASSERT_TRUE(diagnostics);
  msg::Diagnostics d;
  d.line("askagainsvc");
  d.bridge_incarnation(p.incarnation());
  ASSERT_TRUE(diagnostics->write(d));
  ASSERT_TRUE(p.subscribe<srv::Command_RequestPubSubType>(
      lb::ddsl::request_topic(path), QosKind::command,
      [&](const srv::Command_Request& rq, const lb::ddsl::fdds::SampleInfo& info) {
        {
          std::lock_guard lock(m);
          seen.push_back(
              {info.sample_identity, info.related_sample_identity, rq.device(), rq.command(), rq.bridge_incarnation()});
        }
        if (info.related_sample_identity == SampleIdentity::unknown()) return;  // the first answer "lost"
        srv::Command_Response r;
        r.success(true);
        r.frames(6);
        r.held_ms(120.0);
        r.bridge_incarnation(rq.bridge_incarnation());
        eprosima::fastrtps::rtps::WriteParams params;
        params.related_sample_identity(info.related_sample_identity);
        answers.write(r, params);
      }));

  const auto r = run_cli({"press", "saw1", "manual_cut", "--timeout", "8", "--config", config});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r, "manual_cut: on the bus in 6 RPDO(s) over 120.0 ms")) << r.output;
  std::lock_guard lock(m);
  ASSERT_EQ(seen.size(), 2u) << "asked again once, after the first answer did not come";
  EXPECT_EQ(seen[0].related, SampleIdentity::unknown()) << "the first request names none";
  EXPECT_EQ(seen[1].related, seen[0].self) << "the repeat names the first request";
  EXPECT_NE(seen[1].self, seen[0].self);
  EXPECT_EQ(seen[1].device, "saw1");
  EXPECT_EQ(seen[1].command, "manual_cut");
  EXPECT_EQ(seen[0].run, p.incarnation()) << "the first request names the run the CLI heard of";
  EXPECT_EQ(seen[1].run, seen[0].run) << "the repeat names the same run";
}

// The field names of one struct of an IDL text, in order ("uint64 frames_in;" gives frames_in).
std::vector<std::string> idl_fields(const std::string& idl, const std::string& structure) {
  const auto begin = idl.find("struct " + structure + " {");
  if (begin == std::string::npos) return {};
  const auto end = idl.find("};", begin);
  std::vector<std::string> fields;
  std::istringstream body(idl.substr(begin, end - begin));
  const std::regex field(R"(^\s*[A-Za-z_][\w:]*(<[^>]*>)?\s+(\w+)\s*;)");
  for (std::string line; std::getline(body, line);) {
    if (std::smatch m; std::regex_search(line, m, field)) fields.push_back(m[2]);
  }
  return fields;
}

// A saw's status line, exactly: the change-of-length bit is a toggle (CiA 420-4 6020h bit 2: "each
// change shall force the saw to take over the new length setting"), shown with its level among the
// set values, never as a button pressed; a momentary command the control word carries is pressed.
TEST(CliText, ASawsChangeOfLengthToggleIsShownAsAToggleNotPressed) {
  msg::SawStatus s;
  s.health().nmt_state(msg::NMT_OPERATIONAL);
  s.health().online(true);
  s.health().active_errors_known(true);
  s.status_word().raw(0x1001);
  s.status_word().saw_ready(true);
  s.status_word().saw_program_enabled(true);
  s.counter_value(2500);
  s.actual_saw_counter_m(0.25);
  s.product_speed_m_per_min(27.0);
  s.control_word().raw(0x0005);
  s.control_word().saw_program_on(true);
  s.control_word().change_of_length(true);
  s.sync_speed_set_percent(90.0);
  s.product_length_set_m(1.0);
  const auto clock = lb::app::clock_text(s.stamp());
  EXPECT_EQ(lb::app::to_text(s),
            clock +
                " operational     online  | saw counter   0.2500 m  speed  27.000 m/min  pulses       2500 | status "
                "1001h [saw_ready saw_program_enabled] | set: program on, smooth pipe, wall-thickening off, length "
                "1.0000 m, sync 90.00 %, toggles [change_of_length=1]");
  s.control_word().raw(0x0009);
  s.control_word().change_of_length(false);
  s.control_word().manual_cut(true);
  EXPECT_EQ(lb::app::to_text(s),
            clock +
                " operational     online  | saw counter   0.2500 m  speed  27.000 m/min  pulses       2500 | status "
                "1001h [saw_ready saw_program_enabled] | set: program on, smooth pipe, wall-thickening off, length "
                "1.0000 m, sync 90.00 %, toggles [change_of_length=0], pressed [manual_cut]");
}

// `linebridge-cli echo bridge diagnostics` prints every field of the Diagnostics type: the field
// list is read from idl/common.idl, so a field added there and not printed fails here. Each is
// printed under its name (underscores as hyphens), or, for the few shown as their value alone,
// as the value this test puts in.
TEST(CliText, DiagnosticsTextShowsEveryIdlField) {
  std::ifstream in(std::string(LB_SOURCE_DIR) + "/idl/common.idl");
  const std::string idl((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  msg::Diagnostics d;
  d.line("lineX");
  msg::BusDiagnostics b;
  b.name("busX");
  b.interface_uri("socketcan:vcanX");
  b.role("master");
  b.state("error-passive");
  d.buses().push_back(b);
  msg::NodeDiagnostics n;
  n.device("deviceX");
  n.bus("busX");
  n.node_id(42);
  d.nodes().push_back(n);
  const auto text = lb::app::to_text(d);
  // Shown as their value (or a unit), not under their own name; the containers are their parts.
  const std::map<std::string, std::string> shown_as = {{"stamp", ":"},
                                                       {"line", "lineX"},
                                                       {"buses", "busX"},
                                                       {"nodes", "deviceX"},
                                                       {"dds_side", "dds-side"},
                                                       {"name", "busX"},
                                                       {"interface_uri", "socketcan:vcanX"},
                                                       {"role", "master"},
                                                       {"state", "error-passive"},
                                                       {"frames_in_per_s", "/s)"},
                                                       {"frames_out_per_s", "/s)"},
                                                       {"load_percent", "load"},
                                                       {"tx_error_counter", "TEC"},
                                                       {"rx_error_counter", "REC"},
                                                       {"device", "deviceX"},
                                                       {"bus", "busX"},
                                                       {"node_id", "node  42"},
                                                       {"online", "OFFLINE"},
                                                       {"nmt_state", "unknown"},
                                                       {"last_heartbeat_age_s", "last-heartbeat-age"}};
  std::size_t checked = 0;
  for (const char* structure : {"Diagnostics", "BusDiagnostics", "NodeDiagnostics", "DdsSideDiagnostics"}) {
    const auto fields = idl_fields(idl, structure);
    EXPECT_GT(fields.size(), 4u) << structure << " not found in idl/common.idl";
    for (const auto& f : fields) {
      ++checked;
      std::string label = f;
      std::replace(label.begin(), label.end(), '_', '-');
      if (const auto it = shown_as.find(f); it != shown_as.end()) label = it->second;
      EXPECT_NE(text.find(label), std::string::npos)
          << structure << "." << f << " is not printed (looked for '" << label << "'):\n"
          << text;
    }
  }
  EXPECT_GT(checked, 60u);
}
