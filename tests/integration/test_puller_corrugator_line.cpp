// Puller (CiA 420-2 1.0 and 3.0-status) and corrugator (CiA 420-3 3.1) end to end: the real
// simulator and the real bridge as separate processes on a virtual bus, this test as an independent
// DDS participant and as a third bus member that watches the frames. Runs inside
// launch_scripts/netns-run.sh (CTest does that).
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/corrugatorPubSubTypes.h"
#include "msgs/pullerPubSubTypes.h"
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
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::uint8_t kPuller = 6, kCorrugator = 7, kPuller30 = 8;
constexpr std::uint16_t kLocalMode = 0x2100, kLocalSpeed = 0x2101;  // DriveSimulator's local panel

using lb::test::CommandClient;
using lb::test::GetClient;
using lb::test::SetClient;
using lb::test::WriteClient;

class PullerCorrugatorLine : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(std::getenv("LINEBRIDGE_NETNS") != nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
    const std::string tag = std::to_string(::getpid());
    bus_uri_ = "virtual:it-drive-" + tag;
    config_path_ = ::testing::TempDir() + "/drive_line_" + tag + ".yaml";
    // 60 m/min at 100 %, 60 m/min/s: the speed takes a second from 0 to 100 %, 50 SYNC cycles.
    const auto device = [](const char* name, int node, const char* profile, const char* version) {
      return std::string("  - name: ") + name + "\n    bus: ext\n    node_id: " + std::to_string(node) +
             "\n    profile: " + profile + "\n    version: '" + version +
             "'\n    heartbeat_timeout_ms: 400\n"
             "    simulation: {max_speed_m_per_min: 60, acceleration_m_per_min_s: 60, heartbeat_period_ms: 100}\n";
    };
    std::ofstream(config_path_) << "line: itest\n"
                                   "dds: {domain: 4, localhost_only: true}\n"
                                   "buses:\n"
                                   "  - {name: ext, interface: '" +
                                       bus_uri_ +
                                       "', role: master, sync_period_ms: 20}\n"
                                       "devices:\n" +
                                       device("puller1", kPuller, "cia420-2", "1.0") +
                                       device("corr1", kCorrugator, "cia420-3", "3.1") +
                                       device("puller3", kPuller30, "cia420-2", "3.0-status");
    spy_ = std::make_unique<lb::test::BusSpy>(bus_uri_);
    sim_ = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", config_path_},
                                                    ::testing::TempDir() + "/drive_sim_" + tag + ".log");
    bridge_ = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_BRIDGE, "--config",
                                                                                config_path_},
                                                       ::testing::TempDir() + "/drive_bridge_" + tag + ".log");
    ASSERT_TRUE(sim_->started());
    ASSERT_TRUE(bridge_->started());

    auto dds = lb::ddsl::Participant::create({4, true, "itest"});
    ASSERT_TRUE(dds) << dds.error().message;
    dds_ = std::move(*dds);
    ASSERT_TRUE(puller_.subscribe(*dds_, topic("puller1", "status"), lb::ddsl::QosKind::state));
    ASSERT_TRUE(puller30_.subscribe(*dds_, topic("puller3", "status"), lb::ddsl::QosKind::state));
    ASSERT_TRUE(corrugator_.subscribe(*dds_, topic("corr1", "status"), lb::ddsl::QosKind::state));
    for (const char* dev : {"puller1", "corr1", "puller3"}) {
      ASSERT_TRUE(results_.subscribe(*dds_, topic(dev, "setpoint_result"), lb::ddsl::QosKind::reply));
    }
    auto pw = dds_->writer<msg::PullerSetpointPubSubType>(topic("puller1", "setpoint"), lb::ddsl::QosKind::command);
    auto p3w = dds_->writer<msg::PullerSetpointPubSubType>(topic("puller3", "setpoint"), lb::ddsl::QosKind::command);
    auto cw = dds_->writer<msg::CorrugatorSetpointPubSubType>(topic("corr1", "setpoint"), lb::ddsl::QosKind::command);
    ASSERT_TRUE(pw && p3w && cw);
    puller_setpoint_ = *pw;
    puller30_setpoint_ = *p3w;
    corrugator_setpoint_ = *cw;

    // Every service client before the devices come up: by the time a test calls one, discovery has
    // matched both directions (a reply written before the server matched a new client is lost).
    // The services are line-wide (itest/bridge/<service>): one client each serves every device.
    auto c = CommandClient::create(*dds_, lb::ddsl::line_service_path("itest", "command"));
    auto g = GetClient::create(*dds_, lb::ddsl::line_service_path("itest", "get_parameter"));
    auto p = SetClient::create(*dds_, lb::ddsl::line_service_path("itest", "set_parameter"));
    auto w = WriteClient::create(*dds_, lb::ddsl::line_service_path("itest", "sdo_write"));
    ASSERT_TRUE(c && g && p && w);
    commands_ = std::move(*c);
    gets_ = std::move(*g);
    sets_ = std::move(*p);
    writes_ = std::move(*w);
    const auto operational = [](const auto& s) { return lb::test::operational(s); };
    ASSERT_TRUE(puller_.wait_last(15s, operational)) << logs();
    ASSERT_TRUE(corrugator_.wait_last(15s, operational)) << logs();
    ASSERT_TRUE(puller30_.wait_last(15s, operational)) << logs();
    ASSERT_TRUE(lb::test::eventually(10s, [&] {
      return puller_setpoint_.matched() > 0 && puller30_setpoint_.matched() > 0 && corrugator_setpoint_.matched() > 0 &&
             dds_->matched_writers(topic("puller1", "setpoint_result")) > 0;
    })) << logs();
  }

  void TearDown() override {
    commands_.reset();  // clients before the participant they live in
    gets_.reset();
    sets_.reset();
    writes_.reset();
    dds_.reset();
    if (bridge_) {
      EXPECT_EQ(bridge_->stop(), 0) << "the bridge did not exit cleanly on SIGTERM\n" << logs();
    }
    if (sim_) sim_->stop();
  }

  static std::string topic(const char* dev, const char* t) { return lb::ddsl::topic_name("itest", dev, t); }
  std::string logs() const {
    return "--- bridge log ---\n" + (bridge_ ? bridge_->log() : "") + "--- sim log ---\n" + (sim_ ? sim_->log() : "");
  }

  template <class Writer, class Setpoint>
  msg::SetpointResult send(Writer& writer, Setpoint sp) {
    sp.request_id(++request_id_);
    EXPECT_TRUE(writer.write(sp));
    msg::SetpointResult answer;
    const bool got = results_.wait(5s, [&](const auto& all) {
      for (const auto& r : all) {
        if (r.request_id() == sp.request_id()) return answer = r, true;
      }
      return false;
    });
    EXPECT_TRUE(got) << "no answer to request " << sp.request_id() << "\n" << logs();
    return answer;
  }
  msg::SetpointResult set_puller(lb::ddsl::Writer<msg::PullerSetpointPubSubType>& w, bool extruder, double percent) {
    msg::PullerSetpoint sp;
    sp.extruder_running(extruder);
    sp.speed_set_percent(percent);
    return send(w, sp);
  }
  srv::Command_Response command(const std::string& device, const std::string& name) {
    srv::Command_Request req;
    req.device(device);
    req.command(name);
    return lb::test::call(*commands_, req, 5s);
  }
  srv::GetParameter_Response get(const std::string& device, const std::string& parameter) {
    srv::GetParameter_Request req;
    req.device(device);
    req.parameter(parameter);
    return lb::test::call(*gets_, req, 5s);
  }
  srv::SetParameter_Response set(const std::string& device, const std::string& parameter, double value) {
    srv::SetParameter_Request req;
    req.device(device);
    req.parameter(parameter);
    req.value(value);
    return lb::test::call(*sets_, req, 5s);
  }
  srv::SdoWrite_Response sdo_write(const std::string& device, std::uint16_t index, const std::string& type,
                                   std::int64_t v) {
    srv::SdoWrite_Request req;
    req.device(device);
    req.index(index);
    req.sub_index(0);
    req.value().data_type(type);
    if (type.rfind("INTEGER", 0) == 0)
      req.value().integer_value(v);
    else
      req.value().unsigned_value(static_cast<std::uint64_t>(v));
    return lb::test::call(*writes_, req, 5s);
  }

  std::string bus_uri_, config_path_;
  std::unique_ptr<lb::test::BusSpy> spy_;
  std::unique_ptr<lb::test::ChildProcess> sim_, bridge_;
  std::unique_ptr<lb::ddsl::Participant> dds_;
  lb::test::Collector<msg::PullerStatusPubSubType> puller_, puller30_;
  lb::test::Collector<msg::CorrugatorStatusPubSubType> corrugator_;
  lb::test::Collector<msg::SetpointResultPubSubType> results_;
  lb::ddsl::Writer<msg::PullerSetpointPubSubType> puller_setpoint_, puller30_setpoint_;
  lb::ddsl::Writer<msg::CorrugatorSetpointPubSubType> corrugator_setpoint_;
  std::unique_ptr<CommandClient> commands_;
  std::unique_ptr<GetClient> gets_;
  std::unique_ptr<SetClient> sets_;
  std::unique_ptr<WriteClient> writes_;
  std::uint64_t request_id_ = 100;
};

}  // namespace

TEST_F(PullerCorrugatorLine, MotorStartIsHeldAtLeast100msThenReleasedAndTheSpeedRampsToTheSetValue) {
  spy_->clear();
  const auto started = command("puller1", "motor_start");
  ASSERT_TRUE(started.success()) << started.message();
  ASSERT_TRUE(puller_.wait_last(5s, [](const auto& s) { return s.status_word().motor_running(); })) << logs();
  // The answer comes once the button is released: RPDO1 frames stamped after it follow the release.
  ASSERT_TRUE(lb::test::wait_frames_after(*spy_, 0x200 + kPuller, lb::test::bus_now_ns(), 3)) << logs();

  // RPDO1 (206h): control word bit 1 (motor start) set in consecutive frames for >= 100 ms, then 0.
  const auto frames = spy_->frames(0x200 + kPuller);
  std::int64_t first = 0, released = 0;
  int pressed_frames = 0;
  for (const auto& f : frames) {
    ASSERT_EQ(f.len, 4) << "RPDO1: control word and speed set value";
    const bool on = (f.data[0] & 0x02) != 0;
    if (on && first == 0) first = f.timestamp_ns;
    if (on) {
      EXPECT_EQ(released, 0) << "motor start pressed twice";
      ++pressed_frames;
    }
    if (!on && first != 0 && released == 0) released = f.timestamp_ns;
  }
  ASSERT_NE(first, 0) << "motor start never reached the bus";
  ASSERT_NE(released, 0) << "motor start was never released";
  // Held 100 ms from the press, sent at every 20 ms SYNC: five frames, and the first frame without
  // it 100 ms after the first with it (less the spy's reception jitter).
  EXPECT_GE(pressed_frames, 5);
  EXPECT_GE(released - first, 95'000'000) << "held " << (released - first) / 1000 << " us";
  EXPECT_LT(released - first, 300'000'000) << "held far longer than the button press";

  // 50 % over DDS: RPDO1 40 00 88 13 (extruder running, 5000) and the speed ramps up to it.
  const std::size_t before = puller_.size();
  const auto ok = set_puller(puller_setpoint_, true, 50.0);
  ASSERT_TRUE(ok.accepted()) << ok.reason();
  ASSERT_TRUE(puller_.wait_last(5s, [](const auto& s) { return std::abs(s.speed_actual_percent() - 50.0) < 0.011; }))
      << logs();
  const auto samples = puller_.samples();
  bool ramped = false;
  double previous = 0;
  for (std::size_t i = before; i < samples.size(); ++i) {
    const double v = samples[i].speed_actual_percent();
    EXPECT_GE(v + 1e-9, previous) << "the speed ramps up monotonically";
    ramped = ramped || (v > 5.0 && v < 45.0);
    previous = v;
  }
  EXPECT_TRUE(ramped) << "no intermediate speed seen: not a ramp";
  // A few status samples more (one per SYNC) than the one that reached the set value: the values
  // below are those the puller holds there, not those of the moment it got there.
  const std::size_t reached = puller_.size();
  ASSERT_TRUE(puller_.wait(10s, [&](const auto& v) { return v.size() >= reached + 5; })) << logs();
  const auto last = puller_.samples().back();
  EXPECT_TRUE(last.control_word().extruder_running());
  EXPECT_DOUBLE_EQ(last.speed_set_percent(), 50.0);
  EXPECT_DOUBLE_EQ(last.speed_set_echo_percent(), 50.0);
  EXPECT_NEAR(last.product_speed_m_per_min(), 30.0, 0.01);  // 50 % of 6003h = 60 m/min
  EXPECT_NEAR(last.load_actual_percent(), 45.0, 0.02);      // the simulator: 15 % + 0.6 x speed
  EXPECT_FALSE(last.set_echo_mismatch());
  EXPECT_FALSE(last.manufacturer_status_word_present());
  bool seen = false;
  for (const auto& f : spy_->frames(0x200 + kPuller)) {
    seen = seen || (f.len == 4 && f.data[0] == 0x40 && f.data[1] == 0x00 && f.data[2] == 0x88 && f.data[3] == 0x13);
  }
  EXPECT_TRUE(seen) << "RPDO1 40 00 88 13 not seen";

  // Motor stop: the speed ramps back to 0 and the motor no longer runs.
  ASSERT_TRUE(command("puller1", "motor_stop").success());
  ASSERT_TRUE(puller_.wait_last(5s, [](const auto& s) {
    return !s.status_word().motor_running() && std::abs(s.speed_actual_percent() - 0.0) < 1e-6;
  })) << logs();
}

TEST_F(PullerCorrugatorLine, CorrugatorRunsAtItsSetValueAndRequestsCuts) {
  ASSERT_TRUE(command("corr1", "drive_start").success());
  ASSERT_TRUE(corrugator_.wait_last(5s, [](const auto& s) {
    return s.status_word().drive_running() && s.status_word().master_extruder_enabled();
  })) << logs();
  msg::CorrugatorSetpoint sp;
  sp.extruder_running(true);
  sp.speed_set_percent(100.0);  // 60 m/min: a cut request every metre, every second
  const auto ok = send(corrugator_setpoint_, sp);
  ASSERT_TRUE(ok.accepted()) << ok.reason();
  ASSERT_TRUE(corrugator_.wait_last(5s, [](const auto& s) {
    return std::abs(s.speed_actual_percent() - 100.0) < 1e-6;
  })) << logs();
  ASSERT_TRUE(corrugator_.wait_last(5s, [](const auto& s) { return s.status_word().start_cut_pulse(); })) << logs();
  const auto last = corrugator_.samples().back();
  EXPECT_NEAR(last.product_speed_m_per_min(), 60.0, 1e-9);
  EXPECT_DOUBLE_EQ(last.speed_set_echo_percent(), 100.0);
  EXPECT_TRUE(last.control_word().extruder_running());

  // Out of range: refused with the reason, never on the bus.
  sp.speed_set_percent(100.5);
  const auto refused = send(corrugator_setpoint_, sp);
  EXPECT_FALSE(refused.accepted());
  EXPECT_NE(refused.reason().find("speed_set_percent"), std::string::npos) << refused.reason();
  const auto unknown = command("corr1", "motor_start");  // a puller's command
  EXPECT_FALSE(unknown.success());
  EXPECT_NE(unknown.message().find("drive_start"), std::string::npos) << unknown.message();
}

TEST_F(PullerCorrugatorLine, ConfigurationParametersByNameInEngineeringUnits) {
  // 6003h speed set maximum: 60 m/min in the simulator = 60000 mm/min.
  auto max = get("puller1", "puller_speed_set_maximum");
  ASSERT_TRUE(max.success()) << max.message();
  EXPECT_DOUBLE_EQ(max.value(), 60.0);
  EXPECT_EQ(max.unit(), "m/min");
  EXPECT_EQ(max.raw(), 60000);
  const auto written = set("puller1", "puller_speed_set_maximum", 30.0);
  ASSERT_TRUE(written.success()) << written.message();
  EXPECT_EQ(written.raw(), 30000);
  EXPECT_DOUBLE_EQ(get("puller1", "puller_speed_set_maximum").value(), 30.0);

  // 6005h speed step (puller: INTEGER16 -10000..10000), 6007h scaling factor, 600Ah pressure.
  EXPECT_TRUE(set("puller1", "puller_speed_step", -2.5).success());
  EXPECT_EQ(get("puller1", "puller_speed_step").raw(), -250);
  const auto step = set("puller1", "puller_speed_step", 150.0);
  EXPECT_FALSE(step.success());
  EXPECT_NE(step.message().find("out of range"), std::string::npos) << step.message();
  EXPECT_TRUE(set("puller1", "scaling_factor", 12345).success());
  EXPECT_EQ(get("puller1", "scaling_factor").raw(), 12345);
  EXPECT_TRUE(set("puller1", "pressure_set_value", 55.55).success());
  EXPECT_EQ(get("puller1", "pressure_set_value").raw(), 5555);
  EXPECT_TRUE(set("puller1", "height_adjustment", 0.125).success());  // 0.1 mm: 1250
  EXPECT_EQ(get("puller1", "height_adjustment").raw(), 1250);
  const auto pressure = set("puller1", "pressure_set_value", 100.01);
  EXPECT_FALSE(pressure.success());
  EXPECT_NE(pressure.message().find("out of range"), std::string::npos) << pressure.message();

  // Corrugator: 6005h is UNSIGNED16 0..10000; 6009h/600Ah are arrays; 600Bh is read-only.
  const auto negative_step = set("corr1", "corrugator_speed_step", -1.0);
  EXPECT_FALSE(negative_step.success());
  EXPECT_NE(negative_step.message().find("out of range"), std::string::npos) << negative_step.message();
  EXPECT_TRUE(set("corr1", "height_adjustment_2", -0.0123).success());
  EXPECT_EQ(get("corr1", "height_adjustment_2").raw(), -123);
  EXPECT_TRUE(set("corr1", "pressure_set_value_10", 12.5).success());
  EXPECT_DOUBLE_EQ(get("corr1", "pressure_set_value_10").value(), 12.5);
  const auto temperature = get("corr1", "actual_temperature_1");
  ASSERT_TRUE(temperature.success()) << temperature.message();
  EXPECT_EQ(temperature.unit(), "°C");
  const auto ro = set("corr1", "actual_temperature_1", 20.0);
  EXPECT_FALSE(ro.success());
  EXPECT_NE(ro.message().find("not writable"), std::string::npos) << ro.message();
  EXPECT_EQ(get("corr1", "height_adjustment_count").raw(), 10);
}

TEST_F(PullerCorrugatorLine, SetEchoMismatchFlaggedWhileThePullerRunsLocally) {
  ASSERT_TRUE(command("puller3", "motor_start").success());
  const auto ok = set_puller(puller30_setpoint_, true, 40.0);
  ASSERT_TRUE(ok.accepted()) << ok.reason();
  ASSERT_TRUE(puller30_.wait_last(5s, [](const auto& s) {
    return std::abs(s.speed_actual_percent() - 40.0) < 1e-6 &&
           s.status_word().speed_set_mode() == msg::PULLER_SPEED_SET_REMOTE;
  })) << logs();
  EXPECT_FALSE(puller30_.samples().back().set_echo_mismatch());

  // The operator switches the puller to its local panel at 25 %: it echoes 25 %, not 40 %.
  ASSERT_TRUE(sdo_write("puller3", kLocalSpeed, "INTEGER16", 2500).success());
  ASSERT_TRUE(sdo_write("puller3", kLocalMode, "UNSIGNED8", 1).success());
  ASSERT_TRUE(puller30_.wait_last(5s, [](const auto& s) { return s.set_echo_mismatch(); })) << logs();
  const auto last = puller30_.samples().back();
  EXPECT_DOUBLE_EQ(last.speed_set_echo_percent(), 25.0);
  EXPECT_DOUBLE_EQ(last.speed_set_percent(), 40.0);
  EXPECT_EQ(last.status_word().speed_set_mode(), msg::PULLER_SPEED_SET_LOCAL);
  ASSERT_TRUE(puller30_.wait_last(5s, [](const auto& s) { return std::abs(s.speed_actual_percent() - 25.0) < 1e-6; }))
      << logs();
  // Only a lasting difference: the echo changed one SYNC after the mode, the flag came later.
  {
    const auto all = puller30_.samples();
    std::size_t changed = 0, flagged = 0;
    for (std::size_t i = 0; i < all.size(); ++i) {
      if (changed == 0 && all[i].speed_set_echo_percent() == 25.0) changed = i;
      if (flagged == 0 && all[i].set_echo_mismatch()) flagged = i;
    }
    EXPECT_GT(flagged, changed);
  }
  EXPECT_NE(bridge_->log().find("set echo"), std::string::npos) << logs();

  // Back to remote: the echo agrees again and the flag clears.
  ASSERT_TRUE(sdo_write("puller3", kLocalMode, "UNSIGNED8", 0).success());
  ASSERT_TRUE(puller30_.wait_last(5s, [](const auto& s) {
    return !s.set_echo_mismatch() && std::abs(s.speed_set_echo_percent() - 40.0) < 1e-6 &&
           s.status_word().speed_set_mode() == msg::PULLER_SPEED_SET_REMOTE;
  })) << logs();
  // The 1.0 puller reports no speed set mode.
  EXPECT_EQ(puller_.samples().back().status_word().speed_set_mode(), msg::PULLER_SPEED_SET_NOT_REPORTED);
}
