// Mandatory devices (CiA 302-2 1F81h bit 3) as the bus shows them, with the real bridge and
// simulators: the saw is mandatory, two pullers are not, and the saw runs in a simulator process
// of its own so that it can be absent, killed and brought back. Expected frames written by hand
// from CiA 301: NMT on identifier 000h, byte 0 the command (01h start, 02h stop, 80h enter
// pre-operational), byte 1 the node-ID (saw 5, pullers 3 and 4); SDO requests to node n on 600h + n.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <string>
#include <thread>

#include "msgs/pullerPubSubTypes.h"
#include "support/line_harness.hpp"
#include "support/scratch_files.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using lb::ddsl::QosKind;

namespace {

std::string device(const std::string& name, int node_id, const std::string& profile, const std::string& version,
                   const std::string& extra = "") {
  return "  - name: " + name + "\n    bus: b\n    node_id: " + std::to_string(node_id) + "\n    profile: " + profile +
         "\n    version: '" + version + "'\n    heartbeat_timeout_ms: 400\n    boot_retry_ms: 1000\n" + extra;
}
std::string pullers() { return device("puller1", 3, "cia420-2", "1.0") + device("puller2", 4, "cia420-2", "1.0"); }
// The bridge's line: the saw mandatory. The pullers' simulator plays only the pullers.
std::string line_devices() { return device("saw1", 5, "cia420-4", "3.1", "    mandatory: true\n") + pullers(); }

bool nmt(const lb::can::CanFrame& f, std::uint8_t command, std::uint8_t node) {
  return f.id == 0x000 && f.len == 2 && f.data[0] == command && f.data[1] == node;
}

const msg::NodeDiagnostics* node(const msg::Diagnostics& d, const std::string& device) {
  for (const auto& n : d.nodes()) {
    if (n.device() == device) return &n;
  }
  return nullptr;
}
// The bus's mandatory state while the saw is absent: waiting for it while its first boot tries,
// and "missing" with the reason once a try failed (its SDO timeout). Which of the two a sample
// shows depends on how fast the pullers' boot is against the saw's 1 s SDO timeout, not on the
// bridge's correctness: both name the saw.
bool names_the_absent_saw(const std::string& state) {
  return state.find("waiting for mandatory device saw1") != std::string::npos ||
         state.find("mandatory device missing (saw1: its boot failed") != std::string::npos;
}
const msg::BusDiagnostics* bus(const msg::Diagnostics& d) { return d.buses().empty() ? nullptr : &d.buses().front(); }

class MandatoryDevicesLine : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  }

  // The saw's own simulator: the saw powers up (pre-operational, boot-up) when it starts.
  void start_saw(lb::test::LineHarness& line) {
    saw_sim = std::make_unique<lb::test::ChildProcess>(
        std::vector<std::string>{LB_BIN_SIM, "--config", line.bridge_config(), "--device", "saw1"},
        ::testing::TempDir() + "/mandatory_saw_sim_" + std::to_string(::getpid()) + ".log");
    ASSERT_TRUE(saw_sim->started());
  }
  std::string logs(lb::test::LineHarness& line) {
    return line.logs() + "--- saw sim log ---\n" + (saw_sim ? saw_sim->log() : "");
  }

  // The timestamp of the first frame since the spy was cleared that matches, within the deadline (0: none).
  template <class Pred>
  static std::int64_t first(lb::test::LineHarness& line, Pred pred, std::chrono::seconds deadline = 30s) {
    const auto end = std::chrono::steady_clock::now() + deadline;
    do {
      for (const auto& f : line.spy().frames()) {
        if (pred(f)) return f.timestamp_ns;
      }
      std::this_thread::sleep_for(20ms);
    } while (std::chrono::steady_clock::now() < end);
    return 0;
  }
  static std::size_t count(lb::test::LineHarness& line, std::uint8_t command, std::uint8_t node_id) {
    const auto frames = line.spy().frames();
    return static_cast<std::size_t>(std::count_if(frames.begin(), frames.end(), [&](const lb::can::CanFrame& f) {
      return nmt(f, command, node_id);
    }));
  }
  // Waits until `n` more diagnostics samples arrived (each one is a second of the bridge's life).
  bool more_samples(std::size_t n) {
    const auto target = diag.size() + n;
    return diag.wait(30s, [&](const std::vector<msg::Diagnostics>& v) { return v.size() >= target; });
  }

  lb::test::Collector<msg::DiagnosticsPubSubType> diag;
  std::unique_ptr<lb::test::ChildProcess> saw_sim;
};

// Start-up with the mandatory saw absent: both pullers are checked and configured (SDO) and then
// wait pre-operational; no NMT start reaches them, and diagnostics name the saw. Once the saw's
// simulator starts and its boot passes, the saw is started and then both pullers.
TEST_F(MandatoryDevicesLine, AStartWaitsUntilTheMandatoryDevicePassedItsBoot) {
  lb::test::LineHarness line("mandatory", 67);
  line.start(line_devices(), pullers());
  ASSERT_TRUE(diag.subscribe(line.dds(), line.topic("bridge", "diagnostics"), QosKind::state));

  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    const auto* b = bus(d);
    const auto* p1 = node(d, "puller1");
    const auto* p2 = node(d, "puller2");
    return b != nullptr && p1 != nullptr && p2 != nullptr && b->mandatory_missing().size() == 1 &&
           b->mandatory_missing()[0] == "saw1" && names_the_absent_saw(b->mandatory_state()) &&
           p1->line_hold().find("waiting for mandatory device saw1") != std::string::npos &&
           p2->line_hold().find("waiting for mandatory device saw1") != std::string::npos &&
           p1->node_state() == "waiting for a mandatory device";
  })) << logs(line);
  {
    const auto d = diag.samples().back();
    EXPECT_TRUE(node(d, "saw1")->mandatory());
    EXPECT_FALSE(node(d, "puller1")->mandatory());
    EXPECT_FALSE(node(d, "puller2")->mandatory());
  }
  // Configured: the boot's SDO requests went to both pullers.
  EXPECT_NE(first(
                line, [](const lb::can::CanFrame& f) { return f.id == 0x603; }, 1s),
            0)
      << "puller1 was not configured";
  EXPECT_NE(first(
                line, [](const lb::can::CanFrame& f) { return f.id == 0x604; }, 1s),
            0)
      << "puller2 was not configured";
  // Two more seconds of the bridge's life (two diagnostics samples later): still no NMT start.
  ASSERT_TRUE(more_samples(2));
  EXPECT_EQ(count(line, 0x01, 3), 0u) << "puller1 started before the mandatory saw passed its boot";
  EXPECT_EQ(count(line, 0x01, 4), 0u) << "puller2 started before the mandatory saw passed its boot";
  EXPECT_NE(line.bridge().log().find("waiting for mandatory device saw1"), std::string::npos) << logs(line);

  start_saw(line);
  const auto saw_start = first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x01, 5); });
  const auto p1_start = first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x01, 3); });
  const auto p2_start = first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x01, 4); });
  ASSERT_NE(saw_start, 0) << "the saw was never started\n" << logs(line);
  ASSERT_NE(p1_start, 0) << "puller1 was never started\n" << logs(line);
  ASSERT_NE(p2_start, 0) << "puller2 was never started\n" << logs(line);
  EXPECT_LE(saw_start, p1_start);
  EXPECT_LE(saw_start, p2_start);
  // The saw's SDO requests (its boot) came before its start, and every one of the pullers' before theirs.
  const auto saw_sdo = first(
      line, [](const lb::can::CanFrame& f) { return f.id == 0x605; }, 1s);
  ASSERT_NE(saw_sdo, 0);
  EXPECT_LT(saw_sdo, saw_start);
  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    const auto* b = bus(d);
    return b != nullptr && b->mandatory_missing().empty() && b->mandatory_state().empty() &&
           node(d, "puller1")->line_hold().empty() && node(d, "puller2")->line_hold().empty() &&
           node(d, "puller1")->node_state() == "operational" && node(d, "puller2")->node_state() == "operational" &&
           node(d, "saw1")->node_state() == "operational";
  })) << logs(line);
}

// The line runs; the mandatory saw's simulator is killed. After the heartbeat timeout both pullers
// get NMT stop (when_mandatory_fails: stop_others, the default). A stopping command still reaches
// a held puller. The saw comes back and is booted and started, but neither puller is started again
// by the bridge; an operator's nmt start starts puller1, and puller2 stays stopped.
TEST_F(MandatoryDevicesLine, ALostMandatoryDeviceStopsTheOthersUntilAnOperatorStartsThem) {
  lb::test::LineHarness line("mandatory", 68);
  line.start(line_devices(), pullers());
  start_saw(line);
  ASSERT_TRUE(diag.subscribe(line.dds(), line.topic("bridge", "diagnostics"), QosKind::state));
  auto results = line.collect<msg::SetpointResultPubSubType>("puller1", "setpoint_result", QosKind::reply);
  auto setpoint = line.dds().writer<msg::PullerSetpointPubSubType>(line.topic("puller1", "setpoint"), QosKind::command);
  ASSERT_TRUE(setpoint);
  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    for (const char* n : {"saw1", "puller1", "puller2"}) {
      const auto* x = node(d, n);
      if (x == nullptr || x->node_state() != "operational") return false;
    }
    return true;
  })) << logs(line);
  ASSERT_GE(count(line, 0x01, 3), 1u);
  ASSERT_GE(count(line, 0x01, 4), 1u);

  ASSERT_EQ(count(line, 0x02, 3) + count(line, 0x02, 4), 0u);
  ::kill(saw_sim->pid(), SIGKILL);  // the saw loses power: no boot-up, no heartbeat
  const auto p1_stop = first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x02, 3); });
  const auto p2_stop = first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x02, 4); });
  ASSERT_NE(p1_stop, 0) << "puller1 was not stopped when the mandatory saw was lost\n" << logs(line);
  ASSERT_NE(p2_stop, 0) << "puller2 was not stopped when the mandatory saw was lost\n" << logs(line);
  saw_sim->stop();
  // After the heartbeat timeout (400 ms) counted from the saw's last heartbeat.
  std::int64_t last_heartbeat = 0;
  for (const auto& f : line.spy().frames(0x705)) {
    if (f.timestamp_ns < p1_stop) last_heartbeat = std::max(last_heartbeat, f.timestamp_ns);
  }
  ASSERT_NE(last_heartbeat, 0) << "no heartbeat of the saw seen before the stop";
  EXPECT_GE(p1_stop - last_heartbeat, 350'000'000) << "stopped before the heartbeat timeout";
  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    const auto* b = bus(d);
    const auto* p1 = node(d, "puller1");
    const auto* p2 = node(d, "puller2");
    return b != nullptr && b->mandatory_missing().size() == 1 && b->mandatory_missing()[0] == "saw1" &&
           b->mandatory_state().find("stop_others") != std::string::npos && p1 != nullptr && p2 != nullptr &&
           p1->line_hold().rfind("stopped: mandatory device saw1", 0) == 0 &&
           p2->line_hold().rfind("stopped: mandatory device saw1", 0) == 0 &&
           p1->node_state() == "stopped by the line" && p1->nmt_state() == msg::NMT_STOPPED &&
           p2->nmt_state() == msg::NMT_STOPPED;
  })) << logs(line);

  // A stopping command still reaches a held device: the operator's NMT stop (on the bus), and a
  // set value that enables nothing (extruder stopped) is taken.
  const auto before = count(line, 0x02, 4);
  const auto stop = line.nmt("puller2", srv::NMT_STOP);
  ASSERT_TRUE(stop.success()) << stop.message();
  const auto end = std::chrono::steady_clock::now() + 10s;
  while (count(line, 0x02, 4) == before && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(20ms);
  EXPECT_GT(count(line, 0x02, 4), before) << "the operator's NMT stop never reached the held puller2";
  bool taken = false;
  for (int i = 0; i < 20 && !taken; ++i) {
    msg::PullerSetpoint p;
    p.request_id(7);
    p.extruder_running(false);
    p.speed_set_percent(10);
    setpoint->write(p);
    taken = results.wait(1s, [](const std::vector<msg::SetpointResult>& v) {
      return std::any_of(v.begin(), v.end(),
                         [](const msg::SetpointResult& r) { return r.request_id() == 7 && r.accepted(); });
    });
  }
  EXPECT_TRUE(taken) << "a set value that stops puller1 was refused while the line holds it\n" << logs(line);

  // The saw comes back (powers up): booted and started again; the pullers are not.
  line.spy().clear();
  start_saw(line);
  const auto saw_start = first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x01, 5); });
  ASSERT_NE(saw_start, 0) << "the mandatory saw was not started again after it came back\n" << logs(line);
  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    const auto* b = bus(d);
    return b != nullptr && b->mandatory_missing().empty() && node(d, "saw1")->node_state() == "operational";
  })) << logs(line);
  ASSERT_TRUE(more_samples(3));  // three more seconds of the bridge's life
  EXPECT_EQ(count(line, 0x01, 3), 0u) << "puller1 was started again by the bridge, not by an operator";
  EXPECT_EQ(count(line, 0x01, 4), 0u) << "puller2 was started again by the bridge, not by an operator";
  {
    const auto d = diag.samples().back();
    EXPECT_EQ(node(d, "puller1")->nmt_state(), msg::NMT_STOPPED);
    EXPECT_EQ(node(d, "puller2")->nmt_state(), msg::NMT_STOPPED);
    EXPECT_NE(node(d, "puller1")->line_hold().find("nmt start releases it"), std::string::npos)
        << node(d, "puller1")->line_hold();
    EXPECT_NE(bus(d)->mandatory_state().find("kept stopped until an operator starts them: puller1"), std::string::npos)
        << bus(d)->mandatory_state();
  }

  // The operator starts puller1: on the bus and running; puller2 stays stopped.
  const auto go = line.nmt("puller1", srv::NMT_START);
  ASSERT_TRUE(go.success()) << go.message();
  EXPECT_NE(first(
                line, [](const lb::can::CanFrame& f) { return nmt(f, 0x01, 3); }, 10s),
            0)
      << logs(line);
  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    const auto* p1 = node(d, "puller1");
    return p1 != nullptr && p1->node_state() == "operational" && p1->line_hold().empty() &&
           p1->nmt_state() == msg::NMT_OPERATIONAL;
  })) << logs(line);
  EXPECT_EQ(count(line, 0x01, 4), 0u) << "puller2 was started with puller1";
  EXPECT_EQ(diag.samples().back().nodes().size(), 3u);
  EXPECT_EQ(node(diag.samples().back(), "puller2")->nmt_state(), msg::NMT_STOPPED);
}

}  // namespace

// The line's stop outlives the bridge: the mandatory saw is lost and both pullers get NMT stop;
// the saw comes back (the pullers stay stopped); the bridge is killed (SIGKILL) and started again
// on the same state_dir. The restarted bridge boots and starts the saw, boots both pullers and
// puts them back in stopped (000#0203, 000#0204): no NMT start reaches either, their heartbeats say
// stopped (70xh, 04h), diagnostics say the line's hold is from before the restart. An operator's
// nmt start then starts puller1; puller2 stays stopped.
TEST_F(MandatoryDevicesLine, TheLinesStopSurvivesABridgeKill) {
  const auto dir = lb::test::fresh_dir("mandatory-held");
  lb::test::LineHarness line("mandatory", 69);
  line.start(line_devices(), pullers(), "", "state_dir: " + dir + "\n");
  start_saw(line);
  ASSERT_TRUE(diag.subscribe(line.dds(), line.topic("bridge", "diagnostics"), QosKind::state));
  const auto all_operational = [](const msg::Diagnostics& d) {
    for (const char* n : {"saw1", "puller1", "puller2"}) {
      const auto* x = node(d, n);
      if (x == nullptr || x->node_state() != "operational") return false;
    }
    return true;
  };
  ASSERT_TRUE(diag.wait_last(30s, all_operational)) << logs(line);

  ::kill(saw_sim->pid(), SIGKILL);  // the mandatory saw loses power
  ASSERT_NE(first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x02, 3); }), 0) << logs(line);
  ASSERT_NE(first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x02, 4); }), 0) << logs(line);
  saw_sim->stop();
  // The line's holds reach the state directory (waited for, not asserted: the bus below decides).
  const auto file = dir + "/mandatory.holds";
  if (!lb::test::eventually(10s, [&] {
        const auto text = lb::test::read_text(file);
        return text.find("b 3 cia420-2@1.0 ") != std::string::npos &&
               text.find("b 4 cia420-2@1.0 ") != std::string::npos;
      })) {
    ADD_FAILURE() << "the line's holds never reached " << file << ":\n" << lb::test::read_text(file);
  }
  // The saw comes back and is started; the pullers stay stopped.
  start_saw(line);
  ASSERT_NE(first(line, [](const lb::can::CanFrame& f) { return nmt(f, 0x01, 5); }), 0) << logs(line);
  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    const auto* b = bus(d);
    return b != nullptr && b->mandatory_missing().empty() && node(d, "saw1")->node_state() == "operational" &&
           node(d, "puller1")->nmt_state() == msg::NMT_STOPPED && node(d, "puller2")->nmt_state() == msg::NMT_STOPPED;
  })) << logs(line);

  const auto first_run = diag.samples().back().bridge_incarnation();
  ::kill(line.bridge().pid(), SIGKILL);
  ASSERT_TRUE(WIFSIGNALED(line.bridge().stop())) << logs(line);
  line.spy().clear();
  line.start_bridge();

  // The restarted bridge: the saw booted and started, both pullers' boots ended (held or started),
  // three more seconds of its life; no NMT start to either puller, both put back in stopped.
  ASSERT_TRUE(diag.wait(40s,
                        [&](const std::vector<msg::Diagnostics>& v) {
                          if (v.empty() || v.back().bridge_incarnation() == first_run) return false;
                          const auto& d = v.back();
                          const auto* saw = node(d, "saw1");
                          if (saw == nullptr || saw->node_state() != "operational") return false;
                          for (const char* n : {"puller1", "puller2"}) {
                            const auto* p = node(d, n);
                            if (p == nullptr ||
                                (p->node_state() != "operational" && p->node_state() != "stopped by the line"))
                              return false;
                          }
                          return true;
                        }))
      << "the restarted bridge never finished booting the line\n"
      << logs(line);
  ASSERT_TRUE(more_samples(3));
  EXPECT_EQ(count(line, 0x01, 3), 0u) << "the restarted bridge started puller1, which the line holds";
  EXPECT_EQ(count(line, 0x01, 4), 0u) << "the restarted bridge started puller2, which the line holds";
  ASSERT_GE(count(line, 0x02, 3), 1u) << "puller1's boot did not put it back in stopped\n" << logs(line);
  ASSERT_GE(count(line, 0x02, 4), 1u) << "puller2's boot did not put it back in stopped\n" << logs(line);
  EXPECT_NE(first(
                line, [](const lb::can::CanFrame& f) { return f.id == 0x603; }, 1s),
            0)
      << "puller1 not booted";
  EXPECT_NE(first(
                line, [](const lb::can::CanFrame& f) { return f.id == 0x604; }, 1s),
            0)
      << "puller2 not booted";
  for (const std::uint8_t id : {3, 4}) {
    std::int64_t stopped_ns = 0;
    for (const auto& f : line.spy().frames(0x000)) {
      if (nmt(f, 0x02, id)) stopped_ns = f.timestamp_ns;
    }
    std::size_t after = 0;
    for (const auto& f : line.spy().frames(0x700u + id)) {
      if (f.timestamp_ns <= stopped_ns + 150'000'000) continue;  // one period for the device to take it
      ++after;
      EXPECT_TRUE(f.len == 1 && f.data[0] == 0x04) << "node " << int(id) << " left stopped";
    }
    EXPECT_GE(after, 10u) << "node " << int(id);
  }

  // Diagnostics: both held by the line, since before the restart.
  ASSERT_TRUE(diag.wait_last(10s,
                             [](const msg::Diagnostics& d) {
                               for (const char* n : {"puller1", "puller2"}) {
                                 const auto* p = node(d, n);
                                 if (p == nullptr || p->node_state() != "stopped by the line" ||
                                     p->line_hold().rfind("stopped: mandatory device saw1", 0) != 0 ||
                                     p->line_hold().find("kept from before the bridge restarted") == std::string::npos)
                                   return false;
                               }
                               return bus(d) != nullptr &&
                                      bus(d)->mandatory_state().find(
                                          "kept stopped until an operator starts them: puller1") != std::string::npos;
                             }))
      << (diag.samples().empty() || node(diag.samples().back(), "puller1") == nullptr
              ? std::string("(no diagnostics)")
              : node(diag.samples().back(), "puller1")->line_hold());

  // The operator starts puller1: on the bus and running, its hold gone; puller2 stays stopped.
  const auto go = line.nmt("puller1", srv::NMT_START);
  ASSERT_TRUE(go.success()) << go.message();
  EXPECT_NE(first(
                line, [](const lb::can::CanFrame& f) { return nmt(f, 0x01, 3); }, 10s),
            0)
      << logs(line);
  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    const auto* p1 = node(d, "puller1");
    return p1 != nullptr && p1->node_state() == "operational" && p1->line_hold().empty() &&
           p1->nmt_state() == msg::NMT_OPERATIONAL;
  })) << logs(line);
  EXPECT_EQ(count(line, 0x01, 4), 0u) << "puller2 was started with puller1";
  EXPECT_EQ(node(diag.samples().back(), "puller2")->nmt_state(), msg::NMT_STOPPED);
  EXPECT_TRUE(lb::test::eventually(10s,
                                   [&] {
                                     const auto text = lb::test::read_text(file);
                                     return text.find("b 3 cia420-2@1.0 ") == std::string::npos &&
                                            text.find("b 4 cia420-2@1.0 ") != std::string::npos;
                                   }))
      << "puller1's released hold is still kept, or puller2's is gone:\n"
      << lb::test::read_text(file);
}
