// The walking skeleton end to end: the real simulator and the real bridge as separate processes on
// a virtual bus, this test as an independent DDS participant (and as a third bus member that
// watches the frames). Runs inside launch_scripts/netns-run.sh (CTest does that).
#include <gtest/gtest.h>
#include <poll.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/collector.hpp"
#include "support/eventually.hpp"
#include "support/line_harness.hpp"
#include "support/saw_setpoints.hpp"
#include "support/simulated_saw.hpp"
#include "support/spy_waits.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::uint8_t kNode = 5;
// 60 m/min at 100 %: one metre per second, 20 mm per 20 ms SYNC.
constexpr double kStepM = 0.02;

using Statuses = std::vector<msg::SawStatus>;

// The saw counter in the last status sample before each rising edge of "saw cutting", taken from
// the status topic alone (samples from `from` on): where the saw really cut, and whether it was
// shorter than `below` metres.
std::vector<double> cut_lengths(const Statuses& status, std::size_t from, double below = 1e9) {
  std::vector<double> lengths;
  for (std::size_t i = std::max<std::size_t>(from, 1); i < status.size(); ++i) {
    if (status[i].status_word().saw_cutting() && !status[i - 1].status_word().saw_cutting() &&
        status[i - 1].actual_saw_counter_m() < below) {
      lengths.push_back(status[i - 1].actual_saw_counter_m());
    }
  }
  return lengths;
}

class SawLine : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(std::getenv("LINEBRIDGE_NETNS") != nullptr, true)
        << "run through launch_scripts/netns-run.sh (ctest does)";
    line_.start(lb::test::simulated_saw("b"), "", ", role: master, sync_period_ms: 20");
    ASSERT_TRUE(line_.sim().started());
    ASSERT_TRUE(line_.bridge().started());

    const auto topic = [](const char* t) { return lb::ddsl::topic_name("itest", "saw1", t); };
    ASSERT_TRUE(status_.subscribe(line_.dds(), topic("status"), lb::ddsl::QosKind::state));
    ASSERT_TRUE(cuts_.subscribe(line_.dds(), topic("cut"), lb::ddsl::QosKind::event));
    ASSERT_TRUE(cuts_.wait_matched()) << logs();  // a cut reaches only a matched reader
    ASSERT_TRUE(setpoints_.open(line_.dds(), "itest", "saw1"));

    // The device is up and both directions of the set-value exchange are matched.
    ASSERT_TRUE(status_.wait_last(15s, [](const msg::SawStatus& s) {
      return s.health().online() && s.health().nmt_state() == msg::NMT_OPERATIONAL;
    })) << logs();
    setpoints_.wait_matched(10s);
    ASSERT_GT(setpoints_.writer().matched(), 0);
  }

  void TearDown() override {
    if (line_.started()) {
      EXPECT_EQ(line_.bridge().stop(), 0) << "the bridge did not exit cleanly on SIGTERM\n" << logs();
    }
  }

  std::string logs() const { return line_.logs(); }

  msg::SetpointResult send(bool on, double percent, double length_m) {
    const auto answer = setpoints_.send(on, percent, length_m, 5s);
    EXPECT_TRUE(answer) << "no answer to request " << setpoints_.last_request_id() << "\n" << logs();
    return answer.value_or(msg::SetpointResult{});
  }

  std::size_t status_count() { return status_.size(); }

  // linebridge-cli with this line's configuration, run to its end: exit code and output.
  struct CliRun {
    int exit_code;
    std::string output;
  };
  CliRun cli(const std::vector<std::string>& args) {
    std::vector<std::string> argv{LB_BIN_CLI, "--config", line_.bridge_config()};
    argv.insert(argv.end(), args.begin(), args.end());
    lb::test::ChildProcess p(argv, ::testing::TempDir() + "/cli_" + std::to_string(::getpid()) + "_" +
                                       std::to_string(++cli_runs_) + ".log");
    lb::test::eventually(20s, [&] { return !p.running(); });
    const int status = p.stop();
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, p.log()};
  }

  lb::test::Collector<msg::SawStatusPubSubType> status_;  // every sample, not just the latest
  lb::test::Collector<msg::SawCutPubSubType> cuts_;
  lb::test::SawSetpoints setpoints_;
  lb::test::LineHarness line_{"itest", 3};
  int cli_runs_ = 0;
};

bool near_length(double measured, double length) {
  // The counter grows by one SYNC step between samples: the last sample before the cut lies in
  // [length - step, length); allow a second step for scheduling jitter on a loaded machine.
  return measured < length + 1e-9 && measured >= length - 2 * kStepM - 1e-9;
}

}  // namespace

TEST_F(SawLine, ProductLengthSetOverDdsIsWhereTheSawCuts) {
  const auto accepted = send(true, 100.0, 0.5);
  ASSERT_TRUE(accepted.accepted()) << accepted.reason();
  // Cut events and status are separate topics: wait for both to show three cuts.
  ASSERT_TRUE(cuts_.wait(15s, [](const auto& cuts) { return cuts.size() >= 3; })) << logs();
  status_.wait(5s, [](const Statuses& v) { return cut_lengths(v, 0).size() >= 3; });
  const auto lengths = cut_lengths(status_.samples(), 0);
  ASSERT_GE(lengths.size(), 3u);
  for (double l : lengths) EXPECT_PRED2(near_length, l, 0.5);
  for (const auto& c : cuts_.samples()) {
    EXPECT_DOUBLE_EQ(c.length_in_force_m(), 0.5);
    EXPECT_PRED2(near_length, c.counter_before_cut_m(), 0.5);
  }
  EXPECT_DOUBLE_EQ(status_.samples().back().product_length_set_m(), 0.5);
  EXPECT_NEAR(status_.samples().back().product_speed_m_per_min(), 60.0, 1e-9);

  // A new length is taken after the next cut (change-of-length toggle, CiA 420-4 6020h bit 2).
  const std::size_t before = status_count();
  const auto changed = send(true, 100.0, 0.3);
  ASSERT_TRUE(changed.accepted()) << changed.reason();
  ASSERT_TRUE(status_.wait(15s, [&](const Statuses& v) { return cut_lengths(v, before, 0.4).size() >= 2; })) << logs();
  const auto after = cut_lengths(status_.samples(), before);
  ASSERT_GE(after.size(), 3u);
  EXPECT_PRED2(near_length, after.front(), 0.5) << "the new length must not apply before the next cut";
  bool switched = false;
  for (double l : after) {
    if (near_length(l, 0.3)) {
      switched = true;
    } else {
      EXPECT_TRUE(!switched && near_length(l, 0.5)) << "cut at " << l << " m";
    }
  }
  EXPECT_TRUE(switched);
  // The cut events agree with the status topic: each reports the length it was made at.
  for (const auto& c : cuts_.samples()) {
    EXPECT_PRED2(near_length, c.counter_before_cut_m(), c.length_in_force_m()) << "cut #" << c.cut_count();
  }
}

TEST_F(SawLine, OutOfRangeSetValueIsRefusedAndNeverReachesCan) {
  line_.spy().clear();
  const auto refused = send(true, 150.0, 1.0);
  EXPECT_FALSE(refused.accepted());
  EXPECT_NE(refused.reason().find("sync_speed_percent"), std::string::npos) << refused.reason();
  const auto negative = send(true, 50.0, -2.0);
  EXPECT_FALSE(negative.accepted());
  EXPECT_NE(negative.reason().find("product_length_m"), std::string::npos) << negative.reason();

  // The marker before the negative check: RPDO1 frames sent after both refusals (one per SYNC).
  ASSERT_TRUE(lb::test::wait_frames_after(line_.spy(), 0x200 + kNode, lb::test::bus_now_ns(), 5))
      << "the bridge sends RPDO1 at every SYNC\n"
      << logs();
  const auto rpdos = line_.spy().frames(0x200 + kNode);
  for (const auto& f : rpdos) {
    ASSERT_EQ(f.len, 8);
    EXPECT_EQ(f.data, (std::array<std::uint8_t, 8>{})) << "a refused set value changed RPDO1";
  }

  // The bridge is still there and takes a good value: exactly these bytes reach the bus.
  ASSERT_TRUE(line_.bridge().running()) << logs();
  const auto ok = send(true, 50.0, 0.5);
  ASSERT_TRUE(ok.accepted()) << ok.reason();
  const std::array<std::uint8_t, 8> expected{0x05, 0x00, 0x88, 0x13, 0x88, 0x13, 0x00, 0x00};
  EXPECT_TRUE(lb::test::wait_frame(line_.spy(), 0x200 + kNode, [&](const lb::can::CanFrame& f) {
    return f.data == expected;
  })) << "RPDO1 05 00 88 13 88 13 00 00 not seen";
}

TEST_F(SawLine, ShortPdoIsCountedNotDecoded) {
  // A 4-byte TPDO2 (the mapping needs 8) from a misbehaving node: counted, never published as values.
  ASSERT_TRUE(line_.spy().send(lb::can::make_frame(0x280 + kNode, {0xFF, 0xFF, 0xFF, 0x7F})));
  ASSERT_TRUE(status_.wait_last(10s, [](const msg::SawStatus& s) { return s.pdo_length_errors() >= 1; })) << logs();
  for (const auto& s : status_.samples()) {
    EXPECT_LT(std::abs(s.actual_saw_counter_m()), 1000.0) << "garbage was decoded";
  }
  EXPECT_TRUE(line_.bridge().running());
  EXPECT_NE(line_.bridge().log().find("not decoded"), std::string::npos) << logs();
}

// The CLI's device commands go through the line-wide services (itest/bridge/<service>, the
// request names the device) and keep their user-facing form.
TEST_F(SawLine, CliCommandsReachTheSawThroughTheLineWideServices) {
  const auto name = cli({"sdo-read", "saw1", "0x1008", "0", "VISIBLE_STRING"});
  EXPECT_EQ(name.exit_code, 0) << name.output << logs();
  EXPECT_NE(name.output.find("1008h:00h = \"linebridge simulated saw saw1 (cia420-4 version 3.1)\""), std::string::npos)
      << name.output;

  const auto before = status_count();
  const auto cut = cli({"press", "saw1", "manual_cut"});
  EXPECT_EQ(cut.exit_code, 0) << cut.output << logs();
  EXPECT_NE(cut.output.find("manual_cut: on the bus in "), std::string::npos) << cut.output;
  // The status shows the bit while it is held.
  EXPECT_TRUE(status_.wait(5s, [&](const Statuses& v) {
    for (std::size_t i = before; i < v.size(); ++i) {
      if (v[i].control_word().manual_cut()) return true;
    }
    return false;
  })) << logs();

  // Refused by the bridge (exit 1, the reason printed); a device the configuration does not have
  // is refused by the CLI itself (exit 2) before anything is sent.
  const auto unknown_object = cli({"get", "saw1", "no_such_object"});
  EXPECT_EQ(unknown_object.exit_code, 1) << unknown_object.output;
  EXPECT_NE(unknown_object.output.find("refused: profile cia420-4@3.1 has no object 'no_such_object'"),
            std::string::npos)
      << unknown_object.output;
  const auto unknown_command = cli({"press", "saw1", "jump"});
  EXPECT_EQ(unknown_command.exit_code, 1) << unknown_command.output;
  EXPECT_NE(unknown_command.output.find("refused: saw1: unknown command 'jump' (manual_cut, "), std::string::npos)
      << unknown_command.output;
  // The identity as line-file lines, from the device itself (the simulator's saw at node 5: vendor
  // 4C42 0000h, product 0420 0004h, serial 5100 0005h), ready to paste under the device's entry.
  const auto identity = cli({"identity", "saw1"});
  EXPECT_EQ(identity.exit_code, 0) << identity.output << logs();
  EXPECT_NE(identity.output.find("    identity:\n      device_type: 0x000001A4"), std::string::npos) << identity.output;
  EXPECT_NE(identity.output.find("      vendor_id: 0x4C420000"), std::string::npos) << identity.output;
  EXPECT_NE(identity.output.find("      product_code: 0x04200004"), std::string::npos) << identity.output;
  EXPECT_NE(identity.output.find("      serial_number: 0x51000005"), std::string::npos) << identity.output;

  const auto unknown_device = cli({"nmt", "saw9", "reset-node"});
  EXPECT_EQ(unknown_device.exit_code, 2) << unknown_device.output;
  EXPECT_NE(unknown_device.output.find("no device saw9 in line itest"), std::string::npos) << unknown_device.output;
}
