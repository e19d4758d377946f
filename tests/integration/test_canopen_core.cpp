// The CANopen master core end to end: boot configuration by SDO, identity, SDO services (abort,
// timeout, segmented strings), a device that never answers, reboot mid-run, heartbeat loss and
// return, EMCY, two buses at once, diagnostics. Real linebridge and linebridge-sim processes on
// virtual buses; this test is a separate DDS participant and a passive bus member.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <fstream>
#include <stdexcept>
#include <thread>

#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/collector.hpp"
#include "support/eventually.hpp"
#include "support/line_views.hpp"
#include "support/service_clients.hpp"
#include "support/spy_waits.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using lb::ddsl::QosKind;

namespace {

class CanopenCore : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
    const std::string tag = std::to_string(::getpid());
    bus_a_ = "virtual:core-a-" + tag;
    const std::string bus_b = "virtual:core-b-" + tag;
    config_ = ::testing::TempDir() + "/core_" + tag + ".yaml";
    std::ofstream(config_)
        << "line: core\n"
           "dds: {domain: 4}\n"
           "buses:\n"
           "  - {name: a, interface: '" +
               bus_a_ +
               "', master_node_id: 1, sdo_timeout_ms: 300}\n"
               "  - {name: b, interface: '" +
               bus_b +
               "'}\n"
               "devices:\n"
               "  - name: saw1\n"
               "    bus: a\n"
               "    node_id: 5\n"
               "    profile: cia420-4\n"
               "    version: '3.1'\n"
               "    heartbeat_timeout_ms: 400\n"
               "    boot_retry_ms: 1000\n"
               "    configure:\n"
               "      - {object: saw_sync_speed_set_maximum, value: 45000}\n"
               "      - {index: 0x1017, sub: 0, type: UNSIGNED16, value: 100}\n"
               "  - {name: saw2, bus: b, node_id: 6, profile: cia420-4, version: '3.1'}\n"
               "  - {name: ghost, bus: a, node_id: 9, profile: cia420-4, version: '3.1', boot_retry_ms: 1000}\n";
    spy_ = std::make_unique<lb::test::BusSpy>(bus_a_);  // first member: the hub lives in this process
    const auto tmp = ::testing::TempDir();
    sim_ = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", config_,
                                                                             "--device", "saw1", "--device", "saw2"},
                                                    tmp + "/core_sim_" + tag + ".log");
    bridge_ = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_BRIDGE, "--config", config_},
                                                       tmp + "/core_bridge_" + tag + ".log");
    auto dds = lb::ddsl::Participant::create({4, true, "core-test"});
    ASSERT_TRUE(dds) << dds.error().message;
    dds_ = std::move(*dds);
    ASSERT_TRUE(saw1_.subscribe(*dds_, topic("saw1", "status"), QosKind::state));
    ASSERT_TRUE(saw2_.subscribe(*dds_, topic("saw2", "status"), QosKind::state));
    ASSERT_TRUE(info_.subscribe(*dds_, topic("saw1", "info"), QosKind::state));
    ASSERT_TRUE(emcy_.subscribe(*dds_, topic("saw1", "emergency"), QosKind::event));
    ASSERT_TRUE(diag_.subscribe(*dds_, topic("bridge", "diagnostics"), QosKind::state));
    ASSERT_TRUE(saw1_.wait_last(15s, [](const msg::SawStatus& s) { return operational(s); })) << logs();
  }

  void TearDown() override {
    reads_.reset();  // clients before the participant they live in
    writes_.reset();
    nmts_.reset();
    dds_.reset();
    if (bridge_) {
      EXPECT_EQ(bridge_->stop(), 0) << "the bridge did not exit cleanly\n" << logs();
    }
    if (sim_) sim_->stop();
  }

  static constexpr auto operational = lb::test::operational<msg::SawStatus>;
  static std::string topic(const std::string& device, const std::string& t) {
    return lb::ddsl::topic_name("core", device, t);
  }
  std::string logs() const {
    return "--- bridge log ---\n" + (bridge_ ? bridge_->log() : "") + "--- sim log ---\n" + (sim_ ? sim_->log() : "");
  }

  srv::SdoRead_Response sdo_read(const std::string& device, std::uint16_t index, std::uint8_t sub,
                                 const std::string& type) {
    auto& client = client_for(reads_, "sdo_read");
    srv::SdoRead_Request req;
    req.device(device);
    req.index(index);
    req.sub_index(sub);
    req.data_type(type);
    return lb::test::call(client, req, 20s);
  }
  srv::SdoWrite_Response sdo_write(const std::string& device, std::uint16_t index, std::uint8_t sub,
                                   srv::ObjectValue v) {
    auto& client = client_for(writes_, "sdo_write");
    srv::SdoWrite_Request req;
    req.device(device);
    req.index(index);
    req.sub_index(sub);
    req.value(std::move(v));
    return lb::test::call(client, req, 20s);
  }
  srv::Nmt_Response nmt(const std::string& device, srv::NmtCommand c) {
    auto& client = client_for(nmts_, "nmt");
    srv::Nmt_Request req;
    req.device(device);
    req.command(c);
    return lb::test::call(client, req, 20s);
  }
  // One client per line-wide service for the whole test (requests name the device): discovery
  // once, not per call.
  template <class Client>
  Client& client_for(std::unique_ptr<Client>& slot, const std::string& service) {
    if (!slot) {
      auto c = Client::create(*dds_, lb::ddsl::line_service_path("core", service));
      if (!c) throw std::runtime_error(c.error().message);
      slot = std::move(*c);
    }
    return *slot;
  }
  static srv::ObjectValue unsigned32(std::uint64_t v) {
    srv::ObjectValue o;
    o.data_type("UNSIGNED32");
    o.unsigned_value(v);
    return o;
  }
  const msg::NodeDiagnostics* node(const msg::Diagnostics& d, const std::string& device) {
    for (const auto& n : d.nodes()) {
      if (n.device() == device) return &n;
    }
    return nullptr;
  }

  pid_t sim_pid() const { return sim_->pid(); }

  std::string bus_a_, config_;
  std::unique_ptr<lb::test::BusSpy> spy_;
  std::unique_ptr<lb::test::ChildProcess> sim_, bridge_;
  std::unique_ptr<lb::ddsl::Participant> dds_;
  std::unique_ptr<lb::test::ReadClient> reads_;
  std::unique_ptr<lb::test::WriteClient> writes_;
  std::unique_ptr<lb::test::NmtClient> nmts_;
  lb::test::Collector<msg::SawStatusPubSubType> saw1_, saw2_;
  lb::test::Collector<msg::DeviceInfoPubSubType> info_;
  lb::test::Collector<msg::EmergencyPubSubType> emcy_;
  lb::test::Collector<msg::DiagnosticsPubSubType> diag_;
};

}  // namespace

TEST_F(CanopenCore, BootConfiguresIdentifiesAndServesTwoBuses) {
  // saw2 on the second bus comes up too.
  ASSERT_TRUE(saw2_.wait_last(10s, [](const msg::SawStatus& s) { return operational(s); })) << logs();
  // The configuration written at boot is in the device: 6006h = 45000 mm/min.
  const auto max = sdo_read("saw1", 0x6006, 0, "UNSIGNED32");
  ASSERT_TRUE(max.success()) << max.message();
  EXPECT_EQ(max.value().unsigned_value(), 45000u);
  // Identity, including 1008h (longer than 4 bytes: a segmented upload).
  ASSERT_TRUE(info_.wait_last(10s, [](const msg::DeviceInfo&) { return true; })) << logs();
  const auto info = info_.samples().back();
  EXPECT_EQ(info.device_name(), "linebridge simulated saw saw1 (cia420-4 version 3.1)");
  EXPECT_EQ(info.profile_number(), 420);
  EXPECT_TRUE(info.profile_matches()) << info.remarks();
  EXPECT_EQ(info.vendor_id(), 0x4C420000u);
  EXPECT_EQ(info.serial_number(), 0x51000005u);
  EXPECT_EQ(info.node_id(), 5);
}

TEST_F(CanopenCore, DeviceThatNeverAnswersIsReportedAndRetriedWithoutBlockingOthers) {
  ASSERT_TRUE(diag_.wait_last(10s, [this](const msg::Diagnostics& d) {
    const auto* ghost = node(d, "ghost");
    const auto* saw = node(d, "saw1");
    return ghost != nullptr && saw != nullptr && !ghost->online() &&
           ghost->boot_state().find("failed (B)") != std::string::npos && ghost->boot_error().code() == "B" &&
           ghost->boot_error().abort_code() == 0x05040000u && saw->online() && saw->boot_state() == "started";
  })) << logs();
  // Retried: the bridge tried at least twice in the meantime.
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  auto count = [this] {
    const auto log = bridge_->log();
    std::size_t n = 0;
    const std::string what = "node 9 does not answer 1000h";
    for (auto pos = log.find(what); pos != std::string::npos; pos = log.find(what, pos + 1)) ++n;
    return n;
  };
  while (count() < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(100ms);
  EXPECT_GE(count(), 2u) << logs();
  // Its service requests are refused at once (it never answered: nothing would), with the
  // reason; saw1's work.
  const auto r = sdo_read("ghost", 0x1000, 0, "UNSIGNED32");
  EXPECT_FALSE(r.success());
  EXPECT_EQ(r.abort_code(), 0u) << r.message();
  EXPECT_NE(r.message().find("offline"), std::string::npos) << r.message();
  EXPECT_TRUE(sdo_read("saw1", 0x1000, 0, "UNSIGNED32").success());
}

TEST_F(CanopenCore, SdoAbortsTimeoutsAndSegmentedStrings) {
  auto r = sdo_read("saw1", 0x6FFF, 0, "UNSIGNED16");
  EXPECT_FALSE(r.success());
  EXPECT_EQ(r.abort_code(), 0x06020000u);
  EXPECT_NE(r.message().find("does not exist"), std::string::npos) << r.message();

  auto w = sdo_write("saw1", 0x6000, 0, unsigned32(1));  // counter value: read-only
  EXPECT_FALSE(w.success());
  EXPECT_EQ(w.abort_code(), 0x06010002u) << w.message();

  srv::ObjectValue speed;
  speed.data_type("UNSIGNED16");
  speed.unsigned_value(10001);  // 6005h: 0..10000
  w = sdo_write("saw1", 0x6005, 0, speed);
  EXPECT_FALSE(w.success());
  EXPECT_EQ(w.abort_code(), 0x06090031u) << w.message();

  // A 90-character string down and up again: segmented transfers both ways.
  std::string text;
  for (int i = 0; i < 9; ++i) text += "0123456789";
  srv::ObjectValue s;
  s.data_type("VISIBLE_STRING");
  s.string_value(text);
  w = sdo_write("saw1", 0x2000, 0, s);
  ASSERT_TRUE(w.success()) << w.message();
  r = sdo_read("saw1", 0x2000, 0, "VISIBLE_STRING");
  ASSERT_TRUE(r.success()) << r.message();
  EXPECT_EQ(r.value().string_value(), text);

  r = sdo_read("saw1", 0x1000, 0, "NOT_A_TYPE");
  EXPECT_FALSE(r.success());
  EXPECT_NE(r.message().find("unknown data type"), std::string::npos) << r.message();
}

// The services are line-wide (core/bridge/<service>): one client reaches every device of both
// buses by the request's device field, and a name the bridge does not serve is refused with the
// names it does serve.
TEST_F(CanopenCore, LineWideServicesRouteByDeviceName) {
  ASSERT_TRUE(saw2_.wait_last(10s, [](const msg::SawStatus& s) { return operational(s); })) << logs();
  // 1018h sub 4, serial number: 51000000h + node-ID in the simulator, so each answer is its device's.
  const auto serial1 = sdo_read("saw1", 0x1018, 4, "UNSIGNED32");
  ASSERT_TRUE(serial1.success()) << serial1.message();
  EXPECT_EQ(serial1.value().unsigned_value(), 0x51000005u);
  const auto serial2 = sdo_read("saw2", 0x1018, 4, "UNSIGNED32");
  ASSERT_TRUE(serial2.success()) << serial2.message();
  EXPECT_EQ(serial2.value().unsigned_value(), 0x51000006u);

  const auto unknown = sdo_read("saw7", 0x1018, 4, "UNSIGNED32");
  EXPECT_FALSE(unknown.success());
  EXPECT_EQ(unknown.abort_code(), 0u);
  EXPECT_NE(unknown.message().find("no device 'saw7' on line core"), std::string::npos) << unknown.message();
  EXPECT_NE(unknown.message().find("devices: saw1, saw2, ghost"), std::string::npos) << unknown.message();
  const auto to_unknown = sdo_write("saw7", 0x6006, 0, unsigned32(1));
  EXPECT_FALSE(to_unknown.success());
  EXPECT_NE(to_unknown.message().find("no device 'saw7'"), std::string::npos) << to_unknown.message();

  // A request without a device is refused and reaches no device: no NMT reset (81h) on the bus.
  spy_->clear();
  const auto nameless = nmt("", srv::NMT_RESET_NODE);
  EXPECT_FALSE(nameless.success());
  EXPECT_NE(nameless.message().find("names no device"), std::string::npos) << nameless.message();
  // The marker: an NMT start of saw1 (already operational: nothing changes) asked after it, on the
  // bus. The service handles requests in turn, so a reset let through would be there before it.
  const auto marker = nmt("saw1", srv::NMT_START);
  ASSERT_TRUE(marker.success()) << marker.message();
  ASSERT_TRUE(lb::test::wait_frame(*spy_, 0x000, [](const lb::can::CanFrame& f) {
    return f.len == 2 && f.data[0] == 0x01 && f.data[1] == 5;
  })) << logs();
  for (const auto& f : spy_->frames(0x000)) EXPECT_NE(f.data[0], 0x81) << "an NMT reset reached the bus";
}

TEST_F(CanopenCore, DeviceRebootedMidRunIsReconfiguredAndRestarted) {
  ASSERT_TRUE(sdo_write("saw1", 0x6006, 0, unsigned32(12345)).success());
  ASSERT_EQ(sdo_read("saw1", 0x6006, 0, "UNSIGNED32").value().unsigned_value(), 12345u);
  const auto before = saw1_.size();
  const auto reply = nmt("saw1", srv::NMT_RESET_NODE);
  ASSERT_TRUE(reply.success()) << reply.message();
  // It leaves operational (boot-up) and comes back operational, started by the bridge again.
  ASSERT_TRUE(saw1_.wait(10s, [&](const std::vector<msg::SawStatus>& v) {
    bool left = false;
    for (std::size_t i = before; i < v.size(); ++i) {
      if (v[i].health().nmt_state() != msg::NMT_OPERATIONAL) left = true;
      if (left && operational(v[i])) return true;
    }
    return false;
  })) << logs();
  // The boot configuration was written again (the reset put the simulator's 6006h back to 30000).
  const auto max = sdo_read("saw1", 0x6006, 0, "UNSIGNED32");
  ASSERT_TRUE(max.success()) << max.message();
  EXPECT_EQ(max.value().unsigned_value(), 45000u);
  ASSERT_TRUE(diag_.wait_last(5s, [this](const msg::Diagnostics& d) {
    const auto* n = node(d, "saw1");
    return n != nullptr && n->boot_ups() >= 1 && n->boot_state() == "started";
  })) << logs();
}

TEST_F(CanopenCore, HeartbeatLossAndReturnFlipOnline) {
  ::kill(sim_pid(), SIGSTOP);
  ASSERT_TRUE(saw1_.wait_last(10s, [](const msg::SawStatus& s) { return !s.health().online(); })) << logs();
  // Not before one timeout (400 ms) after the saw's last heartbeat on the bus, by the stamps: the
  // frame's reception time and the offline sample's own stamp; and within a few timeouts of it (a
  // generous upper bound: a loaded machine delays the check itself, not the rule).
  const auto offline = saw1_.samples().back();
  const std::int64_t offline_ns = std::int64_t{offline.stamp().sec()} * 1'000'000'000 + offline.stamp().nanosec();
  std::int64_t last_heartbeat_ns = 0;
  for (const auto& f : spy_->frames(0x705)) {
    if (f.timestamp_ns <= offline_ns) last_heartbeat_ns = std::max(last_heartbeat_ns, f.timestamp_ns);
  }
  ASSERT_GT(last_heartbeat_ns, 0) << "no heartbeat of the saw on the bus";
  EXPECT_GE(offline_ns - last_heartbeat_ns, 400'000'000) << "offline before its timeout";
  EXPECT_LT(offline_ns - last_heartbeat_ns, 3'000'000'000) << "offline long after its timeout";
  ASSERT_TRUE(diag_.wait_last(10s, [this](const msg::Diagnostics& d) {
    const auto* n = node(d, "saw1");
    return n != nullptr && !n->online() && n->last_heartbeat_age_s() > 0.4;
  })) << logs();
  ::kill(sim_pid(), SIGCONT);
  ASSERT_TRUE(saw1_.wait_last(15s, [](const msg::SawStatus& s) { return operational(s); })) << logs();
  // Key events (docs/operations.md): outside systemd the line carries the fields a journal entry
  // would, the line file's names and the node-ID; online at the start and again after the loss.
  EXPECT_NE(bridge_->log().find("node 5 lost: no heartbeat for 400 ms {LB_EVENT=device_lost LB_LINE=core LB_BUS=a "
                                "LB_DEVICE=saw1 LB_NODE=5 LB_HEARTBEAT_TIMEOUT_MS=400}"),
            std::string::npos)
      << logs();
  EXPECT_TRUE(lb::test::eventually(10s, [this] {
    const auto log = bridge_->log();
    const std::string online = "{LB_EVENT=device_online LB_LINE=core LB_BUS=a LB_DEVICE=saw1 LB_NODE=5 LB_NMT_STATE=";
    return log.find(online, log.find("node 5 lost: no heartbeat")) != std::string::npos;
  })) << logs();
}

TEST_F(CanopenCore, EmergenciesAreEventsAndActiveErrorsInStatus) {
  // After its boot the bridge reads the saw's error register 1001h (0), which clears the list (the
  // device is the truth, and these EMCYs come from the test, not the device): inject after that reading.
  ASSERT_TRUE(bridge_->wait_log("saw1: active errors from the device", 10s)) << logs();
  // An event reaches only a reader already matched (seen: an EMCY sent 1 s after the DDS side was
  // ready, before discovery had matched this reader on a loaded machine, never arrived).
  ASSERT_TRUE(emcy_.wait_matched()) << logs();
  // The saw has an error of its own first (the simulator's 2003h raises 5000h, its 1001h then 01h):
  // the bridge reads 1001h again after an EMCY from a running device and clears what a register of
  // 00h contradicts; with one that reports an error it cannot tell the test's EMCYs from the
  // device's (CAN is not authenticated) and lists them (test_device_truth.cpp has the other case).
  ASSERT_TRUE(sdo_write("saw1", 0x2003, 0, unsigned32(0x5000)).success()) << logs();
  ASSERT_TRUE(saw1_.wait_last(5s, [](const msg::SawStatus& s) {
    return s.health().active_errors() == std::vector<std::uint16_t>{0x5000};
  })) << logs();
  // EMCY 4210h (temperature), error register 09h, manufacturer bytes 01..05, from node 5.
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x85, {0x10, 0x42, 0x09, 0x01, 0x02, 0x03, 0x04, 0x05})));
  ASSERT_TRUE(emcy_.wait_last(5s, [](const msg::Emergency& e) { return e.error_code() == 0x4210; })) << logs();
  const auto e = emcy_.samples().back();
  EXPECT_EQ(e.error_register(), 0x09);
  EXPECT_EQ(e.family(), "temperature");
  EXPECT_EQ(e.manufacturer(), (std::array<std::uint8_t, 5>{1, 2, 3, 4, 5}));
  // The key event's line (docs/operations.md), its fields as the frame has them.
  EXPECT_TRUE(bridge_->wait_log("node 5 EMCY 4210h (temperature), register 09h {LB_EVENT=emcy LB_LINE=core LB_BUS=a "
                                "LB_DEVICE=saw1 LB_NODE=5 LB_EMCY_CODE=4210 LB_EMCY_REGISTER=09 "
                                "LB_EMCY_MANUFACTURER=0102030405}",
                                10s))
      << logs();
  // (The status's error register is the EMCY's 09h, then 01h once the bridge read the device's own.)
  ASSERT_TRUE(saw1_.wait_last(5s, [](const msg::SawStatus& s) {
    return s.health().active_errors() == std::vector<std::uint16_t>{0x5000, 0x4210};
  }));
  // 8130h heartbeat error joins them; the error reset (0000h, register 00h) clears all.
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x85, {0x30, 0x81, 0x11, 0, 0, 0, 0, 0})));
  ASSERT_TRUE(saw1_.wait_last(5s, [](const msg::SawStatus& s) { return s.health().active_errors().size() == 3; }));
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x85, {0x00, 0x00, 0x00, 0, 0, 0, 0, 0})));
  ASSERT_TRUE(
      emcy_.wait_last(5s, [](const msg::Emergency& x) { return x.error_code() == 0 && x.active_errors().empty(); }));
  ASSERT_TRUE(saw1_.wait_last(5s, [](const msg::SawStatus& s) { return s.health().active_errors().empty(); }));
  // A short EMCY is refused, not decoded.
  ASSERT_TRUE(spy_->send(lb::can::make_frame(0x85, {0x10, 0x42})));
  EXPECT_TRUE(bridge_->wait_log("EMCY with 2 bytes ignored", 10s)) << logs();
  EXPECT_EQ(emcy_.samples().back().error_code(), 0);
}

TEST_F(CanopenCore, BridgeProducesItsOwnHeartbeat) {
  // master_node_id 1 (701h), 1000 ms default period: four heartbeats waited for, each operational
  // (05h), spaced by the period by their bus stamps (the median of the three gaps).
  spy_->clear();
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (spy_->frames(0x701).size() < 4) {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "fewer than four bridge heartbeats" << logs();
    std::this_thread::sleep_for(50ms);
  }
  const auto beats = spy_->frames(0x701);
  for (const auto& f : beats) EXPECT_EQ(f.data[0], 0x05);
  std::vector<std::int64_t> gaps;
  for (std::size_t i = 1; i < beats.size(); ++i) gaps.push_back(beats[i].timestamp_ns - beats[i - 1].timestamp_ns);
  std::sort(gaps.begin(), gaps.end());
  EXPECT_GE(gaps[gaps.size() / 2], 800'000'000) << "heartbeat period 1000 ms";
  EXPECT_LE(gaps[gaps.size() / 2], 1'600'000'000) << "heartbeat period 1000 ms";
}
