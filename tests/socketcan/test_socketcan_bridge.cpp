// The real bridge on a real vcan0 (inside launch_scripts/vcan-run.sh), this test as an independent
// DDS participant and can-utils as an independent CAN peer: frames built by hand from the spec and
// injected with cansend become the right DDS samples; a DDS set value becomes exactly the expected
// bytes in candump; a monitor bridge puts nothing on the bus; the link going down and coming back
// (also deleted and re-created) ends with RPDO1 on the bus again; record: and log: round trip.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>
#include <vector>

#include "can/candump_log.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/saw_setpoints.hpp"
#include "support/simulated_saw.hpp"
#include "vcan_tools.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;
using lb::test::cansend;
using lb::test::sh;

namespace {

constexpr std::uint32_t kDomain = 9;
// Saw (node 5), 50 % sync speed, 0.5 m, program on: control word 0005h (program on, change of
// length toggled), 6005h 5000 (0.01 %), 6002h 5000 (0.1 mm). CiA 420-4 RPDO1 = 6020h, 6005h, 6002h.
constexpr const char* kRpdo1 = "205#0500881388130000";

struct Observed {
  std::mutex m;
  std::condition_variable cv;
  std::vector<msg::SawStatus> status;

  template <class Pred>
  bool wait(Clock::duration timeout, Pred pred) {
    std::unique_lock lock(m);
    return cv.wait_for(lock, timeout, [&] { return pred(); });
  }
};

class BridgeOnVcan : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(sh("ip link show vcan0 >/dev/null"), 0) << "no vcan0: run through launch_scripts/vcan-run.sh";
    ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "DDS only inside the VM or a private namespace";
    tag_ = std::to_string(::getpid()) + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name();
    auto dds = lb::ddsl::Participant::create({kDomain, true, "socketcan-test"});
    ASSERT_TRUE(dds) << dds.error().message;
    dds_ = std::move(*dds);
    ASSERT_TRUE(dds_->subscribe<msg::SawStatusPubSubType>(
        topic("status"), lb::ddsl::QosKind::state,
        [this](const msg::SawStatus& s, const auto&) {
          std::lock_guard lock(seen_.m);
          seen_.status.push_back(s);
          seen_.cv.notify_all();
        },
        1000));
    ASSERT_TRUE(setpoints_.open(*dds_, "vcan", "saw1"));
  }

  void TearDown() override {
    dds_.reset();
    if (bridge_) {
      EXPECT_EQ(bridge_->stop(), 0) << "the bridge did not exit cleanly on SIGTERM\n" << logs();
    }
    if (sim_) sim_->stop();
    // A test that deleted vcan0 leaves it back as it found it.
    sh("ip link show vcan0 >/dev/null 2>&1 || ip link add dev vcan0 type vcan; ip link set vcan0 up");
  }

  static std::string topic(const char* t) { return lb::ddsl::topic_name("vcan", "saw1", t); }

  std::string write_config(const std::string& bus_yaml) {
    const std::string path = ::testing::TempDir() + "/line_" + tag_ + "_" + std::to_string(configs_++) + ".yaml";
    std::ofstream(path) << "line: vcan\n"
                           "dds: {domain: " +
                               std::to_string(kDomain) +
                               ", localhost_only: true}\n"
                               "buses:\n"
                               "  - " +
                               bus_yaml +
                               "\n"
                               "devices:\n" +
                               lb::test::simulated_saw("ext");
    return path;
  }

  void start_bridge(const std::string& config) {
    bridge_ = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_BRIDGE, "--config", config},
                                                       ::testing::TempDir() + "/bridge_" + tag_ + ".log");
    ASSERT_TRUE(bridge_->started());
  }
  void start_sim(const std::string& config) {
    sim_ = std::make_unique<lb::test::ChildProcess>(std::vector<std::string>{LB_BIN_SIM, "--config", config},
                                                    ::testing::TempDir() + "/sim_" + tag_ + ".log");
    ASSERT_TRUE(sim_->started());
  }

  std::string logs() const {
    return "--- bridge log ---\n" + (bridge_ ? bridge_->log() : "") + "--- sim log ---\n" + (sim_ ? sim_->log() : "");
  }

  bool online_and_operational(Clock::duration timeout) {
    return seen_.wait(timeout, [this] {
      return !seen_.status.empty() && seen_.status.back().health().online() &&
             seen_.status.back().health().nmt_state() == msg::NMT_OPERATIONAL;
    });
  }

  msg::SetpointResult send_setpoint(bool on, double percent, double length_m) {
    setpoints_.wait_matched(20s);
    const auto answer = setpoints_.send(on, percent, length_m, 10s);
    EXPECT_TRUE(answer) << "no answer to request " << setpoints_.last_request_id() << "\n" << logs();
    return answer.value_or(msg::SetpointResult{});
  }

  std::string tag_;
  int configs_ = 0;
  std::unique_ptr<lb::ddsl::Participant> dds_;
  lb::test::SawSetpoints setpoints_;
  Observed seen_;
  std::unique_ptr<lb::test::ChildProcess> bridge_, sim_;
};

std::size_t count_lines(const std::string& text, const std::string& needle) {
  std::size_t n = 0;
  for (auto pos = text.find(needle); pos != std::string::npos; pos = text.find(needle, pos + 1)) ++n;
  return n;
}

TEST_F(BridgeOnVcan, SetValueOverDdsIsExactlyTheRpdoCandumpSeesAndTheBridgeRecords) {
  const std::string recording = ::testing::TempDir() + "/record_" + tag_ + ".log";
  ::unlink(recording.c_str());
  const auto config = write_config(
      "{name: ext, interface: 'socketcan:vcan0', role: master, sync_period_ms: 20, record: '" + recording + "'}");
  start_sim(config);
  start_bridge(config);
  ASSERT_TRUE(online_and_operational(30s)) << logs();

  lb::test::Candump candump("vcan0");
  const auto ok = send_setpoint(true, 50.0, 0.5);
  ASSERT_TRUE(ok.accepted()) << ok.reason();
  std::this_thread::sleep_for(1s);
  const std::string dumped = candump.text();
  EXPECT_GE(count_lines(dumped, std::string(" vcan0 ") + kRpdo1 + "\n"), 5u) << "RPDO1 at every SYNC\n"
                                                                             << dumped.substr(0, 3000);
  EXPECT_GE(count_lines(dumped, " vcan0 080#\n"), 10u) << "SYNC every 20 ms";
  // Nothing but what the profile defines from the bridge: SYNC, NMT, RPDO1 (node 5), SDO (node 5).
  std::istringstream lines(dumped);
  for (std::string l; std::getline(lines, l);) {
    auto rec = lb::can::parse_log_line(l);
    ASSERT_TRUE(rec && *rec) << l;
    const auto id = (*rec)->frame.id;
    EXPECT_TRUE(id == 0x080 || id == 0x000 || id == 0x185 || id == 0x285 || id == 0x205 || id == 0x705 || id == 0x585 ||
                id == 0x605 || id == 0x085)
        << "unexpected frame " << l;
  }

  ASSERT_EQ(bridge_->stop(), 0) << logs();  // closes the recording
  std::ifstream in(recording);
  const std::string recorded((std::istreambuf_iterator<char>(in)), {});
  EXPECT_GT(count_lines(recorded, " vcan0 080#\n"), 10u) << "sent frames are recorded";
  EXPECT_GT(count_lines(recorded, std::string(" vcan0 ") + kRpdo1 + "\n"), 5u);
  EXPECT_GT(count_lines(recorded, " vcan0 185#"), 10u) << "received frames are recorded";
}

TEST_F(BridgeOnVcan, AfterTheLinkComesBackRpdo1IsOnTheBusAgain) {
  const auto config = write_config("{name: ext, interface: 'socketcan:vcan0', role: master, sync_period_ms: 20}");
  start_sim(config);
  start_bridge(config);
  ASSERT_TRUE(online_and_operational(30s)) << logs();
  ASSERT_TRUE(send_setpoint(true, 50.0, 0.5).accepted());

  for (const auto& [down, up] :
       {std::pair{"ip link set vcan0 down", "ip link set vcan0 up"},
        std::pair{"ip link del vcan0", "ip link add dev vcan0 type vcan && ip link set vcan0 up"}}) {
    ASSERT_EQ(sh(down), 0) << down;
    std::this_thread::sleep_for(1500ms);  // longer than the heartbeat timeout: the saw goes offline
    ASSERT_TRUE(bridge_->running()) << down << "\n" << logs();
    ASSERT_EQ(sh(up), 0) << up;
    lb::test::Candump candump("vcan0", 200ms);
    std::this_thread::sleep_for(2500ms);
    const std::string dumped = candump.text();
    EXPECT_GE(count_lines(dumped, std::string(" vcan0 ") + kRpdo1 + "\n"), 3u)
        << "after '" << down << "' and '" << up << "' the RPDO1 image must be sent again\n"
        << dumped.substr(0, 2000) << logs();
    EXPECT_TRUE(bridge_->running()) << logs();
    EXPECT_TRUE(sim_->running()) << logs();
    EXPECT_TRUE(online_and_operational(5s)) << "the saw is online again on DDS\n" << logs();
  }
}

TEST_F(BridgeOnVcan, InjectedFramesBecomeDdsSamplesMonitorStaysSilentAndTheRecordingReplays) {
  start_bridge(write_config("{name: ext, interface: 'socketcan:vcan0', role: monitor}"));
  std::this_thread::sleep_for(3s);  // the monitor has opened the bus (nothing to wait on: it is silent)

  lb::test::Candump candump("vcan0");
  // Built by hand from CiA 420-4 V3.1 (config/profiles/cia420-4-saw-3.1.yaml):
  // heartbeat of node 5, operational;
  // TPDO1 = 6030h status word (16) 1001h = saw ready + saw program enabled, 6000h counter (32) 12345678h;
  // TPDO2 = 6001h actual saw counter (i32, 0.1 mm) 2500 = 0.25 m, 6007h product speed (i32, mm/min) 30000;
  // RPDO1 from another master: program on, 50 %, 0.5 m.
  const std::vector<std::string> frames = {"705#05", "185#011078563412", "285#C409000030750000", kRpdo1, "705#05"};
  for (const auto& f : frames) {
    ASSERT_TRUE(cansend("vcan0", f)) << f;
    std::this_thread::sleep_for(50ms);
  }
  const auto decoded = [this] {
    return seen_.wait(15s, [this] {
      if (seen_.status.empty()) return false;
      const auto& s = seen_.status.back();
      return s.counter_value() == 0x12345678u && s.control_word().saw_program_on();
    });
  };
  ASSERT_TRUE(decoded()) << logs();
  const auto check = [](const msg::SawStatus& s) {
    EXPECT_EQ(s.status_word().raw(), 0x1001);
    EXPECT_TRUE(s.status_word().saw_ready());
    EXPECT_TRUE(s.status_word().saw_program_enabled());
    EXPECT_FALSE(s.status_word().saw_cutting());
    EXPECT_EQ(s.counter_value(), 0x12345678u);
    EXPECT_DOUBLE_EQ(s.actual_saw_counter_m(), 0.25);
    EXPECT_DOUBLE_EQ(s.product_speed_m_per_min(), 30.0);
    EXPECT_EQ(s.control_word().raw(), 0x0005);
    EXPECT_DOUBLE_EQ(s.sync_speed_set_percent(), 50.0);
    EXPECT_DOUBLE_EQ(s.product_length_set_m(), 0.5);
  };
  {
    std::lock_guard lock(seen_.m);
    check(seen_.status.back());
  }
  std::this_thread::sleep_for(500ms);
  const auto dumped = candump.records();
  ASSERT_EQ(dumped.size(), frames.size()) << "a monitor bridge must put no frame on the bus\n" << candump.text();
  ASSERT_EQ(bridge_->stop(), 0) << logs();
  bridge_.reset();

  // The same frames, from candump's own recording, replayed into a monitor bridge at their pace,
  // after a lead-in of 3 s (one frame of no device): the status writer is keep-last 1, so a test
  // reader that matched the new bridge only after a fast replay got nothing but the latest sample,
  // which may be one stamped when it was published (CI, a loaded VM: "samples carry the recorded
  // time" failed once).
  {
    std::lock_guard lock(seen_.m);
    seen_.status.clear();
  }
  const std::string replayed = ::testing::TempDir() + "/replay_" + tag_ + ".log";
  {
    lb::can::CanFrame lead_in;
    lead_in.id = 0x7FF;
    lead_in.len = 1;
    lead_in.timestamp_ns = dumped.front().frame.timestamp_ns - 3'000'000'000;
    std::ofstream(replayed) << lb::can::format_log_line(lead_in, "vcan0") << candump.text();
  }
  start_bridge(write_config("{name: ext, interface: 'log:" + replayed + "'}"));
  ASSERT_TRUE(decoded()) << logs();
  std::lock_guard lock(seen_.m);
  check(seen_.status.back());
  // Decoded samples carry the time candump recorded for their frame, not the replay's. (The status
  // topic is keep-last 1 at the writer: under load a fast replay may replace a sample before it is
  // delivered, so any of the recorded frames' times will do, not necessarily TPDO2's.)
  bool recorded_stamp = false;
  for (const auto& s : seen_.status) {
    for (const auto& d : dumped) {
      const std::int64_t ns = d.frame.timestamp_ns;
      recorded_stamp = recorded_stamp ||
                       (s.stamp().sec() == static_cast<std::int32_t>(ns / 1'000'000'000) &&
                        s.stamp().nanosec() / 1000 == static_cast<std::uint32_t>(ns % 1'000'000'000 / 1000));
    }
  }
  EXPECT_TRUE(recorded_stamp) << "samples carry the recorded time";
}

}  // namespace
