// PDO overrides in a line file reach the device: the bridge reads every PDO's parameters at boot
// and writes what differs where the profile lets a master write it (CiA 301 sequence, read back).
// The simulator starts from its profile's defaults and learns the rest only over CAN, so what the
// frames show here was really written. Expected values come from the spec tables, written by hand.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <thread>
#include <vector>

#include "msgs/pullerPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/line_harness.hpp"
#include "support/line_views.hpp"
#include "support/set_value_client.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using lb::ddsl::QosKind;

// Saw 3.1: only the transmission parameters are rw (tables 3, 7, 11); the bridge writes them and
// the saw's PDOs follow them on the bus. Its COB-IDs are const, so its PDOs are valid for good and
// CiA 301 forbids writing their inhibit time: this saw comes with 50 ms from its factory (its
// `simulation:`), which the line's 500 x 100 us matches, so nothing is written there.
TEST(PdoOverrides, TransmissionTypesReachTheSawAndItsFramesFollowThem) {
  lb::test::LineHarness line("pdo", 6);
  line.start("  - name: saw1\n"
             "    bus: b\n"
             "    node_id: 5\n"
             "    profile: cia420-4\n"
             "    version: '3.1'\n"
             "    pdos:\n"
             "      tpdo1: {transmission_type: 254, inhibit_time_100us: 500, event_timer_ms: 300}\n"
             "      tpdo2: {transmission_type: 2}\n"
             "      rpdo1: {transmission_type: 255}\n"
             "    simulation: {max_speed_m_per_min: 60, acceleration_m_per_min_s: 6000,\n"
             "                 pdos: {tpdo1: {inhibit_time_100us: 500}}}\n");
  auto info = line.collect<msg::DeviceInfoPubSubType>("saw1", "info", QosKind::state);
  lb::test::SetValueClient<msg::SawStatusPubSubType, msg::SawSetpointPubSubType> saw(line, "saw1");

  // On the bus, the bridge's boot wrote the transmission type (expedited download of 1800h sub 2
  // = 254: 2F 00 18 02 FE) and never the inhibit time (no download to 1800h sub 3): the line's
  // value and the saw's own, both 500 in this file, are the same assumption, so only the absence
  // of a write says something about the bridge here.
  bool type_written = false;
  for (const auto& f : line.spy().frames(0x605)) {
    if (f.len != 8 || (f.data[0] & 0xE0) != 0x20 || f.data[1] != 0x00 || f.data[2] != 0x18) continue;
    EXPECT_NE(f.data[3], 3) << "the bridge wrote the inhibit time of a PDO it cannot make invalid";
    type_written = type_written || (f.data[0] == 0x2F && f.data[3] == 2 && f.data[4] == 254);
  }
  EXPECT_TRUE(type_written) << "1800h sub 2 = 254 never written";
  // In the device now (1800h sub 2/5, 1801h sub 2, 1400h sub 2; sub 3 its own), and reported on info.
  EXPECT_EQ(line.read_unsigned("saw1", 0x1800, 2, "UNSIGNED8"), 254u);
  EXPECT_EQ(line.read_unsigned("saw1", 0x1800, 3, "UNSIGNED16"), 500u);
  EXPECT_EQ(line.read_unsigned("saw1", 0x1800, 5, "UNSIGNED16"), 300u);
  EXPECT_EQ(line.read_unsigned("saw1", 0x1801, 2, "UNSIGNED8"), 2u);
  EXPECT_EQ(line.read_unsigned("saw1", 0x1400, 2, "UNSIGNED8"), 255u);
  ASSERT_TRUE(info.wait_last(5s, [](const msg::DeviceInfo& i) { return i.started(); })) << line.logs();
  const auto started = info.samples().back();
  const auto* tpdo2 = lb::test::pdo_of(started, "tpdo2");
  ASSERT_NE(tpdo2, nullptr);
  EXPECT_EQ(tpdo2->transmission_type(), 2);
  EXPECT_FALSE(tpdo2->adopted());

  // Windows counted in the bridge's SYNCs on the bus (a loaded machine stretches time, not SYNCs).
  const auto wait_syncs = [&line](std::size_t n) { return line.spy().wait_count(0x080, n, 60s).size() >= n; };
  // Quiet line: the event-driven RPDO1 is not repeated at every SYNC.
  line.spy().clear();
  ASSERT_TRUE(wait_syncs(50));
  EXPECT_TRUE(line.spy().frames(0x205).empty()) << "event-driven RPDO1 without a change";

  saw.writer.write(lb::test::saw_set_value(1, 100, 0.5));
  ASSERT_TRUE(saw.answered(1)) << line.logs();
  // 60 m/min, and the saw cuts at 0.5 m.
  ASSERT_TRUE(saw.status.wait(30s, [](const std::vector<msg::SawStatus>& v) {
    bool cut = false;
    for (std::size_t i = 1; i < v.size(); ++i) {
      if (v[i].status_word().saw_cutting() && !v[i - 1].status_word().saw_cutting() &&
          v[i - 1].actual_saw_counter_m() > 0.44 && v[i - 1].actual_saw_counter_m() < 0.5) {
        cut = true;
      }
    }
    return cut && v.back().product_speed_m_per_min() == 60.0;
  })) << line.logs();

  line.spy().clear();
  ASSERT_TRUE(wait_syncs(50));
  std::size_t syncs = 0, tpdo2_frames = 0, rpdo1_frames = 0;
  std::vector<std::int64_t> tpdo1_at;
  for (const auto& f : line.spy().frames()) {
    if (f.extended) continue;
    if (f.id == 0x080) ++syncs;
    if (f.id == 0x285) ++tpdo2_frames;
    if (f.id == 0x185) tpdo1_at.push_back(f.timestamp_ns);
    if (f.id == 0x205) ++rpdo1_frames;
  }
  EXPECT_NEAR(static_cast<double>(tpdo2_frames), syncs / 2.0, 3.0) << "TPDO2 after every 2nd SYNC";
  // TPDO1 carries the pulse counter, which changes at every SYNC: event-driven, it goes out, but
  // at most once per inhibit time of 50 ms (by the frames' send stamps; 45 ms for stamp jitter:
  // the stamp is taken when the frame is sent, right after the simulator's inhibit check).
  EXPECT_GE(tpdo1_at.size(), 5u);
  EXPECT_LT(tpdo1_at.size(), syncs) << "TPDO1 at every SYNC: the inhibit time is not in force";
  for (std::size_t i = 1; i < tpdo1_at.size(); ++i) {
    EXPECT_GE(tpdo1_at[i] - tpdo1_at[i - 1], 45'000'000)
        << "TPDO1 frames " << i - 1 << " and " << i << " closer than the inhibit time";
  }
  EXPECT_EQ(rpdo1_frames, 0u) << "no set value changed in these 50 SYNCs";

  // A new set value: RPDO1 goes out at once, once.
  line.spy().clear();
  saw.writer.write(lb::test::saw_set_value(2, 100, 0.4));
  ASSERT_TRUE(saw.answered(2)) << line.logs();
  // Once: the first RPDO1, then 10 more SYNCs without another.
  ASSERT_FALSE(line.spy().wait_count(0x205, 1).empty()) << "no RPDO1 for the new set value\n" << line.logs();
  ASSERT_TRUE(wait_syncs(line.spy().frames(0x080).size() + 10));
  const auto sent = line.spy().frames(0x205);
  ASSERT_EQ(sent.size(), 1u) << line.logs();
  EXPECT_EQ(sent[0].data[4], 0xA0);  // 0.4 m = 4000 = 0FA0h
  EXPECT_EQ(sent[0].data[5], 0x0F);
  EXPECT_EQ(line.bridge().stop(), 0) << line.logs();
}

// Puller 1.0: the text leaves its mappings CiA 301 rw. A line file that puts the product speed
// first in TPDO2 gets it written with the CiA 301 sequence (sub 0 = 0, entries, sub 0 = 2), and
// the puller's frames and the status decode by the new layout.
TEST(PdoOverrides, RemappedTpdoIsWrittenToTheDeviceAndDecodes) {
  lb::test::LineHarness line("remap", 7);
  line.start("  - name: puller1\n"
             "    bus: b\n"
             "    node_id: 6\n"
             "    profile: cia420-2\n"
             "    version: '1.0'\n"
             "    pdos:\n"
             "      tpdo2: {mapping: [0x60080020, 0x60040010]}\n"
             "    simulation: {max_speed_m_per_min: 30, acceleration_m_per_min_s: 600}\n");
  lb::test::SetValueClient<msg::PullerStatusPubSubType, msg::PullerSetpointPubSubType> puller(line, "puller1");
  EXPECT_EQ(line.read_unsigned("puller1", 0x1A01, 0, "UNSIGNED8"), 2u);
  EXPECT_EQ(line.read_unsigned("puller1", 0x1A01, 1, "UNSIGNED32"), 0x60080020u);
  EXPECT_EQ(line.read_unsigned("puller1", 0x1A01, 2, "UNSIGNED32"), 0x60040010u);

  msg::PullerSetpoint sp;
  sp.request_id(1);
  sp.extruder_running(true);
  sp.speed_set_percent(50);
  puller.writer.write(sp);
  ASSERT_TRUE(
      puller.results.wait_last(5s, [](const msg::SetpointResult& r) { return r.request_id() == 1 && r.accepted(); }));
  ASSERT_TRUE(line.command("puller1", "motor_start").success()) << line.logs();
  // 50 % of 30 m/min = 15 m/min (6008h: 150000 x 0.1 mm/min); the set echo 6004h is 50.00 %.
  ASSERT_TRUE(puller.status.wait_last(10s, [](const msg::PullerStatus& s) {
    return s.product_speed_m_per_min() > 14.99 && s.product_speed_m_per_min() < 15.01 &&
           s.speed_set_echo_percent() > 49.99 && s.speed_set_echo_percent() < 50.01;
  })) << line.logs();
  // The puller's next TPDO2 on the bus, waited for.
  line.spy().clear();
  const auto frames = line.spy().wait_count(0x286, 1);
  ASSERT_FALSE(frames.empty()) << "no TPDO2 of the puller" << line.logs();
  const auto& f = frames.back();
  ASSERT_EQ(f.len, 6);
  // Bytes 0..3 product speed 000249F0h, bytes 4..5 the set echo 1388h: the new order.
  EXPECT_EQ(f.data[0], 0xF0);
  EXPECT_EQ(f.data[1], 0x49);
  EXPECT_EQ(f.data[2], 0x02);
  EXPECT_EQ(f.data[3], 0x00);
  EXPECT_EQ(f.data[4], 0x88);
  EXPECT_EQ(f.data[5], 0x13);
}
