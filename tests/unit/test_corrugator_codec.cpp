// Corrugator decoding and encoding against frames written by hand from the specification (CiA 420-3
// 3.1.0, tables 1-46) and profile-decisions.md (the control and status word layouts the text lost).
// The expected values are typed in here, never computed by the code under test.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "gateways/command_service.hpp"
#include "gateways/drive_codec.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "support/codec_pdo.hpp"

namespace msg = linebridge_msgs::msg;
using CorrugatorCodec = lb::gateways::DriveCodec<linebridge_msgs::bindings::Corrugator>;

namespace {

class CorrugatorCodecTest : public ::testing::Test {
 protected:
  CorrugatorCodecTest()
      : registry_(lb::profiles::ProfileRegistry::builtin()),
        profile_(*registry_.find("cia420-3", "3.1")),
        pdos_(lb::profiles::default_pdos(profile_, 7)) {}

  std::size_t pdo(const std::string& name) const { return lb::test::pdo_index(codec_, name); }
  msg::CorrugatorStatus status() const {
    msg::CorrugatorStatus s;
    codec_.fill(s);
    return s;
  }
  msg::CorrugatorSetpoint setpoint(bool extruder_running, double percent) const {
    msg::CorrugatorSetpoint sp;
    sp.extruder_running(extruder_running);
    sp.speed_set_percent(percent);
    return sp;
  }
  std::array<std::uint8_t, 8> rpdo1() const {
    std::array<std::uint8_t, 8> out{};
    EXPECT_EQ(codec_.pack(pdo("rpdo1"), out), 4);
    return out;
  }

  lb::profiles::ProfileRegistry registry_;
  const lb::profiles::Profile& profile_;
  std::vector<lb::profiles::DevicePdo> pdos_;
  CorrugatorCodec codec_{profile_, pdos_};
};

}  // namespace

TEST_F(CorrugatorCodecTest, DefaultPdoCommunicationFromTheSpec) {
  // Tables 3/7/11: 4000 0180h/0280h/0200h + node-ID (bit 30: no RTR), transmission type 1.
  const auto& p = codec_.pdos();
  EXPECT_EQ(p[pdo("tpdo1")].def->can_id, 0x187u);
  EXPECT_EQ(p[pdo("tpdo2")].def->can_id, 0x287u);
  EXPECT_EQ(p[pdo("rpdo1")].def->can_id, 0x207u);
  for (const auto& x : p) EXPECT_EQ(x.def->transmission_type, 1);
  // Tables 5/9/13.
  EXPECT_EQ(p[pdo("tpdo1")].binding.mapping().byte_length(), 6u);
  EXPECT_EQ(p[pdo("tpdo2")].binding.mapping().byte_length(), 6u);
  EXPECT_EQ(p[pdo("rpdo1")].binding.mapping().byte_length(), 4u);
}

TEST_F(CorrugatorCodecTest, EveryStatusBitHasItsName) {
  using Getter = std::function<bool(const msg::CorrugatorStatusWord&)>;
  const std::vector<std::pair<unsigned, Getter>> bits{
      {0, [](auto& w) { return w.drive_running(); }},
      {1, [](auto& w) { return w.drive_ready_to_start(); }},
      {3, [](auto& w) { return w.fault(); }},
      {4, [](auto& w) { return w.alarm(); }},
      {5, [](auto& w) { return w.increase_request(); }},
      {6, [](auto& w) { return w.decrease_request(); }},
      {7, [](auto& w) { return w.master_extruder_enabled(); }},
      {8, [](auto& w) { return w.f1_running(); }},
      {9, [](auto& w) { return w.f1_ready(); }},
      {10, [](auto& w) { return w.f2_running(); }},
      {11, [](auto& w) { return w.f2_ready(); }},
      {12, [](auto& w) { return w.f3_running(); }},
      {13, [](auto& w) { return w.f3_ready(); }},
      {14, [](auto& w) { return w.start_cut_pulse(); }},
  };
  for (const auto& [bit, get] : bits) {
    const auto word = static_cast<std::uint16_t>(1U << bit);
    const std::array<std::uint8_t, 6> frame{static_cast<std::uint8_t>(word), static_cast<std::uint8_t>(word >> 8), 0, 0, 0, 0};
    ASSERT_TRUE(codec_.receive(pdo("tpdo1"), frame));
    const auto s = status();
    EXPECT_EQ(s.status_word().raw(), word);
    for (const auto& [other, get_other] : bits) {
      EXPECT_EQ(get_other(s.status_word()), other == bit) << "status bit " << bit << " set, field of bit " << other;
    }
  }
  // Bits 2 and 15 are reserved: raw only.
  const std::array<std::uint8_t, 6> reserved{0x04, 0x80, 0, 0, 0, 0};
  ASSERT_TRUE(codec_.receive(pdo("tpdo1"), reserved));
  const auto s = status();
  EXPECT_EQ(s.status_word().raw(), 0x8004);
  for (const auto& [bit, get] : bits) EXPECT_FALSE(get(s.status_word())) << bit;
}

TEST_F(CorrugatorCodecTest, ValuesInEngineeringUnits) {
  // TPDO1: status 0083h (running, ready, master-extruder enabled); 6000h 7550 = 1D7Eh (75.5 %);
  // 6006h 4321 = 10E1h (43.21 % of the maximum load); manufacturer word 1234h.
  const std::array<std::uint8_t, 8> t1{0x83, 0x00, 0x7E, 0x1D, 0xE1, 0x10, 0x34, 0x12};
  ASSERT_TRUE(codec_.receive(pdo("tpdo1"), t1));
  // TPDO2: 6004h 7550 = 1D7Eh; 6008h 0.1 mm/min, -150000 = FFFD B610h (-15 m/min, reversed).
  const std::array<std::uint8_t, 6> t2{0x7E, 0x1D, 0x10, 0xB6, 0xFD, 0xFF};
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), t2));
  const auto s = status();
  EXPECT_TRUE(s.status_word().drive_running());
  EXPECT_TRUE(s.status_word().drive_ready_to_start());
  EXPECT_TRUE(s.status_word().master_extruder_enabled());
  EXPECT_DOUBLE_EQ(s.speed_actual_percent(), 75.5);
  EXPECT_DOUBLE_EQ(s.load_actual_percent(), 43.21);
  EXPECT_TRUE(s.manufacturer_status_word_present());
  EXPECT_EQ(s.manufacturer_status_word(), 0x1234);
  EXPECT_DOUBLE_EQ(s.speed_set_echo_percent(), 75.5);
  EXPECT_DOUBLE_EQ(s.product_speed_m_per_min(), -15.0);
}

TEST_F(CorrugatorCodecTest, SetValueBecomesTheRpdo1Frame) {
  // Extruder running (bit 6) with drive start held (bit 1): 0042h; 75.5 % = 7550 = 1D7Eh.
  codec_.set_control_bit(1, true);
  auto raw = codec_.validate(setpoint(true, 75.5));
  ASSERT_TRUE(raw) << raw.error().message;
  codec_.apply(*raw);
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{0x42, 0x00, 0x7E, 0x1D, 0, 0, 0, 0}));
  const auto s = status();
  EXPECT_TRUE(s.control_word().drive_start());
  EXPECT_TRUE(s.control_word().extruder_running());
  EXPECT_DOUBLE_EQ(s.speed_set_percent(), 75.5);
  // -0.01 % = -1 = FFFFh (reverse is allowed: 6002h -10000..+10000).
  codec_.set_control_bit(1, false);
  codec_.apply(*codec_.validate(setpoint(false, -0.01)));
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{0x00, 0x00, 0xFF, 0xFF, 0, 0, 0, 0}));
}

TEST_F(CorrugatorCodecTest, OutOfRangeSetValuesAreRefusedWithTheReason) {
  auto r = codec_.validate(setpoint(true, 150.0));
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("speed_set_percent"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("out of range"), std::string::npos) << r.error().message;
  EXPECT_FALSE(codec_.validate(setpoint(true, -100.01)));
  EXPECT_TRUE(codec_.validate(setpoint(true, 100.004)));    // 10000.4 -> 10000 raw
  EXPECT_FALSE(codec_.validate(setpoint(true, std::nan(""))));
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{}));
}

TEST_F(CorrugatorCodecTest, EveryControlBitHasItsNameAndTheMomentaryOnesAreCommands) {
  using Getter = std::function<bool(const msg::CorrugatorControlWord&)>;
  const std::vector<std::pair<unsigned, Getter>> bits{
      {0, [](auto& w) { return w.drive_stop(); }},        {1, [](auto& w) { return w.drive_start(); }},
      {2, [](auto& w) { return w.move_in(); }},           {3, [](auto& w) { return w.move_out(); }},
      {6, [](auto& w) { return w.extruder_running(); }},  {7, [](auto& w) { return w.f1_stop(); }},
      {8, [](auto& w) { return w.f1_start(); }},          {9, [](auto& w) { return w.f2_stop(); }},
      {10, [](auto& w) { return w.f2_start(); }},         {11, [](auto& w) { return w.f3_stop(); }},
      {12, [](auto& w) { return w.f3_start(); }},
  };
  for (const auto& [bit, get] : bits) {
    codec_.set_control_bit(bit, true);
    const auto s = status();
    EXPECT_EQ(s.control_word().raw(), 1U << bit);
    for (const auto& [other, get_other] : bits) EXPECT_EQ(get_other(s.control_word()), other == bit) << bit << "/" << other;
    codec_.set_control_bit(bit, false);
  }
  const auto commands = lb::gateways::resolve_commands(codec_.bitset("control_word"),
                                                       lb::gateways::momentary_commands<linebridge_msgs::bindings::Corrugator>());
  const std::vector<std::pair<std::string, unsigned>> expected{
      {"drive_stop", 0}, {"drive_start", 1}, {"move_in", 2}, {"move_out", 3}, {"f1_stop", 7},
      {"f1_start", 8},   {"f2_stop", 9},     {"f2_start", 10}, {"f3_stop", 11}, {"f3_start", 12}};
  ASSERT_EQ(commands.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(commands[i].name, expected[i].first);
    EXPECT_EQ(commands[i].bit, expected[i].second);
  }
}

TEST_F(CorrugatorCodecTest, MonitorRoleComparesTheEchoWithTheRpdo1SeenOnTheBus) {
  // A monitor decodes the line controller's RPDO1 (6002h = 3000 = 0BB8h) and the device's TPDO2.
  const std::array<std::uint8_t, 4> r1{0x40, 0x00, 0xB8, 0x0B};
  ASSERT_TRUE(codec_.receive(pdo("rpdo1"), r1));
  EXPECT_DOUBLE_EQ(status().speed_set_percent(), 30.0);
  const std::array<std::uint8_t, 6> echo{0xD0, 0x07, 0, 0, 0, 0};  // 2000 = 07D0h
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(codec_.receive(pdo("tpdo2"), echo));
  EXPECT_FALSE(status().set_echo_mismatch());
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), echo));
  EXPECT_TRUE(status().set_echo_mismatch());
  EXPECT_DOUBLE_EQ(status().speed_set_echo_percent(), 20.0);
}
