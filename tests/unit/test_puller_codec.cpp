// Puller decoding and encoding against frames written by hand from the specification (CiA 420-2
// 1.0, objects 6000h-6030h, PDO mappings 1A00h/1A01h/1600h) and profile-decisions.md (bit layouts,
// the 3.0 status word). The expected values are typed in here, never computed by the code under test.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "gateways/command_service.hpp"
#include "gateways/drive_codec.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "support/codec_pdo.hpp"

namespace msg = linebridge_msgs::msg;
using PullerCodec = lb::gateways::DriveCodec<linebridge_msgs::bindings::Puller>;

namespace {

class PullerCodecTest : public ::testing::TestWithParam<const char*> {
 protected:
  PullerCodecTest()
      : registry_(lb::profiles::ProfileRegistry::builtin()),
        profile_(*registry_.find("cia420-2", GetParam())),
        pdos_(lb::profiles::default_pdos(profile_, 6)) {}

  std::size_t pdo(const std::string& name) const { return lb::test::pdo_index(codec_, name); }
  msg::PullerStatus status() const {
    msg::PullerStatus s;
    codec_.fill(s);
    return s;
  }
  msg::PullerSetpoint setpoint(bool extruder_running, double percent) const {
    msg::PullerSetpoint sp;
    sp.extruder_running(extruder_running);
    sp.speed_set_percent(percent);
    return sp;
  }
  std::array<std::uint8_t, 8> rpdo1() const {
    std::array<std::uint8_t, 8> out{};
    EXPECT_EQ(codec_.pack(pdo("rpdo1"), out), 4);
    return out;
  }
  // TPDO1: status word (16), speed actual (16), load actual (16), little-endian.
  void tpdo1(std::uint16_t sw, std::uint16_t speed = 0, std::uint16_t load = 0) {
    const std::array<std::uint8_t, 6> f{static_cast<std::uint8_t>(sw), static_cast<std::uint8_t>(sw >> 8),
                                        static_cast<std::uint8_t>(speed), static_cast<std::uint8_t>(speed >> 8),
                                        static_cast<std::uint8_t>(load), static_cast<std::uint8_t>(load >> 8)};
    ASSERT_TRUE(codec_.receive(pdo("tpdo1"), f));
  }

  lb::profiles::ProfileRegistry registry_;
  const lb::profiles::Profile& profile_;
  std::vector<lb::profiles::DevicePdo> pdos_;
  PullerCodec codec_{profile_, pdos_};
};

using Getter = std::function<bool(const msg::PullerStatusWord&)>;

// The bits both versions share (profile-decisions.md "Puller").
std::vector<std::pair<unsigned, Getter>> common_status_bits() {
  return {
      {0, [](auto& w) { return w.motor_running(); }},    {1, [](auto& w) { return w.motor_ready_to_start(); }},
      {2, [](auto& w) { return w.clamp_closed(); }},     {3, [](auto& w) { return w.fault(); }},
      {4, [](auto& w) { return w.alarm(); }},            {5, [](auto& w) { return w.increase_request(); }},
      {6, [](auto& w) { return w.decrease_request(); }}, {8, [](auto& w) { return w.f1_running(); }},
      {9, [](auto& w) { return w.f1_ready(); }},         {10, [](auto& w) { return w.f2_running(); }},
      {11, [](auto& w) { return w.f2_ready(); }},        {12, [](auto& w) { return w.f3_running(); }},
      {13, [](auto& w) { return w.f3_ready(); }},
  };
}

}  // namespace

INSTANTIATE_TEST_SUITE_P(Versions, PullerCodecTest, ::testing::Values("1.0", "3.0-status"));

TEST_P(PullerCodecTest, DefaultPdoCommunicationFromTheSpec) {
  // 2.1-2.3: COB-IDs 180h/280h/200h + node-ID, transmission type 1.
  const auto& p = codec_.pdos();
  EXPECT_EQ(p[pdo("tpdo1")].def->can_id, 0x186u);
  EXPECT_EQ(p[pdo("tpdo2")].def->can_id, 0x286u);
  EXPECT_EQ(p[pdo("rpdo1")].def->can_id, 0x206u);
  for (const auto& x : p) EXPECT_EQ(x.def->transmission_type, 1);
  // 1A00h: 6030h, 6000h, 6006h (16 each); 1A01h: 6004h (16), 6008h (32); 1600h: 6020h, 6002h.
  EXPECT_EQ(p[pdo("tpdo1")].binding.mapping().byte_length(), 6u);
  EXPECT_EQ(p[pdo("tpdo2")].binding.mapping().byte_length(), 6u);
  EXPECT_EQ(p[pdo("rpdo1")].binding.mapping().byte_length(), 4u);
}

TEST_P(PullerCodecTest, EveryCommonStatusBitHasItsName) {
  const auto bits = common_status_bits();
  for (const auto& [bit, get] : bits) {
    const auto word = static_cast<std::uint16_t>(1U << bit);
    tpdo1(word);
    const auto s = status();
    EXPECT_EQ(s.status_word().raw(), word);
    for (const auto& [other, get_other] : bits) {
      EXPECT_EQ(get_other(s.status_word()), other == bit) << "status bit " << bit << " set, field of bit " << other;
    }
  }
}

TEST_P(PullerCodecTest, Version10ReverseDirectionIsBit7AndThe30StatusWordMovesIt) {
  const bool v30 = std::string(GetParam()) == "3.0-status";
  tpdo1(0x0080);  // bit 7: reverse direction in 1.0, reserved in 3.0
  EXPECT_EQ(status().status_word().reverse_direction(), !v30);
  tpdo1(0x4000);  // bit 14: reserved in 1.0, reverse direction in 3.0
  EXPECT_EQ(status().status_word().reverse_direction(), v30);
  EXPECT_EQ(status().status_word().raw(), 0x4000);
  // Bit 15: reserved in 1.0; speed set mode in 3.0 (1 = remote, 0 = local).
  tpdo1(0x8000);
  EXPECT_EQ(status().status_word().speed_set_mode(), v30 ? msg::PULLER_SPEED_SET_REMOTE : msg::PULLER_SPEED_SET_NOT_REPORTED);
  tpdo1(0x0000);
  EXPECT_EQ(status().status_word().speed_set_mode(), v30 ? msg::PULLER_SPEED_SET_LOCAL : msg::PULLER_SPEED_SET_NOT_REPORTED);
}

TEST_P(PullerCodecTest, Tpdo1SpeedAndLoadInHundredthsOfAPercent) {
  // 6000h INTEGER16 5000 = 1388h (50 %); 6006h INTEGER16 -1234 = FB2Eh (-12.34 %).
  const std::array<std::uint8_t, 6> frame{0x03, 0x00, 0x88, 0x13, 0x2E, 0xFB};
  ASSERT_TRUE(codec_.receive(pdo("tpdo1"), frame));
  const auto s = status();
  EXPECT_TRUE(s.status_word().motor_running());
  EXPECT_TRUE(s.status_word().motor_ready_to_start());
  EXPECT_DOUBLE_EQ(s.speed_actual_percent(), 50.0);
  EXPECT_DOUBLE_EQ(s.load_actual_percent(), -12.34);
  EXPECT_FALSE(s.manufacturer_status_word_present()) << "a 6-byte TPDO1 carries no second status word";
  // Reversed: -10000 = D8F0h (-100 %); load at the INTEGER16 limit 32767 = 7FFFh (327.67 %).
  const std::array<std::uint8_t, 6> reversed{0x00, 0x00, 0xF0, 0xD8, 0xFF, 0x7F};
  ASSERT_TRUE(codec_.receive(pdo("tpdo1"), reversed));
  EXPECT_DOUBLE_EQ(status().speed_actual_percent(), -100.0);
  EXPECT_DOUBLE_EQ(status().load_actual_percent(), 327.67);
}

TEST_P(PullerCodecTest, ManufacturerStatusWordPublishedRawWhenTheFrameCarriesIt) {
  // 1A00h note: the unused bytes 6..7 carry only a manufacturer-specific second status word.
  const std::array<std::uint8_t, 8> frame{0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xEF, 0xBE};
  ASSERT_TRUE(codec_.receive(pdo("tpdo1"), frame));
  EXPECT_TRUE(status().manufacturer_status_word_present());
  EXPECT_EQ(status().manufacturer_status_word(), 0xBEEF);
  tpdo1(0x0000);  // the next frame without it: no longer present
  EXPECT_FALSE(status().manufacturer_status_word_present());
  EXPECT_EQ(status().manufacturer_status_word(), 0);
}

TEST_P(PullerCodecTest, Tpdo2EchoAndProductSpeed) {
  // 6004h INTEGER16 2500 = 09C4h (25 %); 6008h INTEGER32 0.1 mm/min 123456 = 0001E240h = 12.3456 m/min,
  // beyond the printed 0..10000 and still published.
  const std::array<std::uint8_t, 6> frame{0xC4, 0x09, 0x40, 0xE2, 0x01, 0x00};
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), frame));
  EXPECT_DOUBLE_EQ(status().speed_set_echo_percent(), 25.0);
  EXPECT_DOUBLE_EQ(status().product_speed_m_per_min(), 12.3456);
}

TEST_P(PullerCodecTest, ShortPdoIsRefusedAndNothingChanges) {
  const std::array<std::uint8_t, 6> good{0xC4, 0x09, 0x40, 0xE2, 0x01, 0x00};
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), good));
  const std::array<std::uint8_t, 5> short_frame{0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
  EXPECT_FALSE(codec_.receive(pdo("tpdo2"), short_frame));
  EXPECT_DOUBLE_EQ(status().speed_set_echo_percent(), 25.0);
}

TEST_P(PullerCodecTest, SetValueBecomesTheRpdo1Frame) {
  // Extruder running = 6020h bit 6 (0040h); 50 % = 5000 = 1388h.
  auto raw = codec_.validate(setpoint(true, 50.0));
  ASSERT_TRUE(raw) << raw.error().message;
  codec_.apply(*raw);
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{0x40, 0x00, 0x88, 0x13, 0, 0, 0, 0}));
  // Reverse: -12.5 % = -1250 = FB1Eh; extruder stopped.
  codec_.apply(*codec_.validate(setpoint(false, -12.5)));
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{0x00, 0x00, 0x1E, 0xFB, 0, 0, 0, 0}));
  const auto s = status();
  EXPECT_FALSE(s.control_word().extruder_running());
  EXPECT_DOUBLE_EQ(s.speed_set_percent(), -12.5);
  // 12.345 % -> 1234.5 raw -> 1235 (half away from zero).
  EXPECT_EQ(codec_.validate(setpoint(true, 12.345))->speed_set, 1235u);
}

TEST_P(PullerCodecTest, MomentaryBitsKeepTheSetValueAndTheSetValueKeepsThem) {
  codec_.set_control_bit(1, true);  // motor start held
  codec_.apply(*codec_.validate(setpoint(true, 100.0)));
  // 0042h; 100 % = 10000 = 2710h.
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{0x42, 0x00, 0x10, 0x27, 0, 0, 0, 0}));
  EXPECT_TRUE(status().control_word().motor_start());
  codec_.set_control_bit(1, false);
  EXPECT_EQ(rpdo1()[0], 0x40);
}

TEST_P(PullerCodecTest, OutOfRangeSetValuesAreRefusedWithTheReason) {
  // 6002h: -10000..10000 (-100..100 %).
  auto r = codec_.validate(setpoint(true, 100.01));
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("speed_set_percent"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("out of range"), std::string::npos) << r.error().message;
  EXPECT_FALSE(codec_.validate(setpoint(true, -100.01)));
  EXPECT_TRUE(codec_.validate(setpoint(true, -100.0)));
  EXPECT_FALSE(codec_.validate(setpoint(true, std::nan(""))));
  EXPECT_FALSE(codec_.validate(setpoint(true, std::numeric_limits<double>::infinity())));
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{}));
}

TEST_P(PullerCodecTest, EveryControlBitHasItsNameAndTheMomentaryOnesAreCommands) {
  using CGetter = std::function<bool(const msg::PullerControlWord&)>;
  const std::vector<std::pair<unsigned, CGetter>> bits{
      {0, [](auto& w) { return w.motor_stop(); }},        {1, [](auto& w) { return w.motor_start(); }},
      {2, [](auto& w) { return w.clamp_close(); }},       {3, [](auto& w) { return w.clamp_open(); }},
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
  const auto commands =
      lb::gateways::resolve_commands(codec_.bitset("control_word"), lb::gateways::momentary_commands<linebridge_msgs::bindings::Puller>());
  const std::vector<std::pair<std::string, unsigned>> expected{
      {"motor_stop", 0}, {"motor_start", 1}, {"clamp_close", 2}, {"clamp_open", 3}, {"f1_stop", 7},
      {"f1_start", 8},   {"f2_stop", 9},     {"f2_start", 10},   {"f3_stop", 11},   {"f3_start", 12}};
  ASSERT_EQ(commands.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(commands[i].name, expected[i].first);
    EXPECT_EQ(commands[i].bit, expected[i].second);
  }
}

TEST_P(PullerCodecTest, SetEchoDifferenceIsFlaggedOnlyAfterTheSettlingTime) {
  codec_.apply(*codec_.validate(setpoint(true, 50.0)));  // 6002h = 5000
  // TPDO2 with echo 0: the device has not taken the value yet. Three samples are settling time.
  const std::array<std::uint8_t, 6> old_echo{0x00, 0x00, 0x00, 0x00, 0x00, 0x00};
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(codec_.receive(pdo("tpdo2"), old_echo));
    EXPECT_FALSE(status().set_echo_mismatch()) << "sample " << i;
  }
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), old_echo));
  EXPECT_TRUE(status().set_echo_mismatch());
  EXPECT_DOUBLE_EQ(status().speed_set_echo_percent(), 0.0);
  // 4999 = 1387h: within the tolerance of 1 raw unit, clears it.
  const std::array<std::uint8_t, 6> close{0x87, 0x13, 0x00, 0x00, 0x00, 0x00};
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), close));
  EXPECT_FALSE(status().set_echo_mismatch());
  // 4998 = 1386h: two units off, flagged after the settling time again.
  const std::array<std::uint8_t, 6> off{0x86, 0x13, 0x00, 0x00, 0x00, 0x00};
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(codec_.receive(pdo("tpdo2"), off));
  EXPECT_TRUE(status().set_echo_mismatch());
  // A new set value restarts the settling time.
  codec_.apply(*codec_.validate(setpoint(true, 49.98)));
  EXPECT_FALSE(status().set_echo_mismatch());
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), off));
  EXPECT_FALSE(status().set_echo_mismatch());
}
