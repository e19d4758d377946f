// Puller profile CiA 420-2 1.0 (spec file 001, sections 2 and 3.1) and its 3.0 status word variant,
// against the specification tables and profile-decisions.md. Frames are written by hand
// (little-endian) and decoded by the production PDO codec; expected values are typed in.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <optional>
#include <vector>

#include "support/profile_spec.hpp"

using namespace lb::test::spec;

namespace {

const Bits kControl{{"motor_stop", 0},       {"motor_start", 1}, {"clamp_close", 2}, {"clamp_open", 3},
                    {"extruder_running", 6}, {"f1_stop", 7},     {"f1_start", 8},    {"f2_stop", 9},
                    {"f2_start", 10},        {"f3_stop", 11},    {"f3_start", 12}};

// The status word bits 1.0 and the 3.0 variant share (spec section 2; profile-decisions.md
// "Puller"): only reverse direction moves (bit 7 -> 14) and 3.0 adds speed set mode (bit 15).
const Bits kStatusShared{{"motor_running", 0}, {"motor_ready_to_start", 1}, {"clamp_closed", 2},     {"fault", 3},
                         {"alarm", 4},         {"increase_request", 5},     {"decrease_request", 6}, {"f1_running", 8},
                         {"f1_ready", 9},      {"f2_running", 10},          {"f2_ready", 11},        {"f3_running", 12},
                         {"f3_ready", 13}};

class PullerProfile : public ::testing::Test {
 protected:
  lb::profiles::ProfileRegistry registry_ = lb::profiles::ProfileRegistry::builtin();
  const Profile& p_ = *registry_.find("cia420-2", "1.0");
  const Profile& p30_ = *registry_.find("cia420-2", "3.0-status");
};

// Status 0301h (motor running, f1 running, f1 ready); speed -2500 = F63Ch (-25.00 %);
// load 12345 = 3039h (123.45 %: load has the full INTEGER16 range).
const std::vector<Value> kTpdo1{{0x6030, 0, 0x0301}, {0x6000, 0, 0xF63C, -25.0}, {0x6006, 0, 0x3039, 123.45}};
const std::vector<Flag> kTpdo1Flags{{"status_word", "motor_running", 1},
                                    {"status_word", "f1_running", 1},
                                    {"status_word", "f1_ready", 1},
                                    {"status_word", "motor_ready_to_start", 0}};
// Control 0042h (motor start, extruder running); speed set -12.34 % = -1234 = FB2Eh.
const std::vector<Value> kRpdo1{{0x6020, 0, 0x0042}, {0x6002, 0, 0xFB2E, -12.34}};

const auto kFrames = frames_of(
    "cia420-2", "1.0",
    {
        {"Tpdo1StatusSpeedAndLoad", "tpdo1", {0x01, 0x03, 0x3C, 0xF6, 0x39, 0x30}, kTpdo1, kTpdo1Flags},
        // No second status word in a 6-byte frame; 8 bytes carry one: ABCDh.
        {"Tpdo1WithManufacturerStatusWord",
         "tpdo1",
         {0x01, 0x03, 0x3C, 0xF6, 0x39, 0x30, 0xCD, 0xAB},
         kTpdo1,
         kTpdo1Flags,
         0xABCD},
        {"Tpdo1ShortFrameIsRefused", "tpdo1", {0x01, 0x03, 0x3C, 0xF6, 0x39}, {}, {}, std::nullopt, true},
        // Echo 10000 = 2710h (100.00 %); product speed 123456 = 0001 E240h in 0.1 mm/min = 12.3456 m/min.
        {"Tpdo2EchoAndProductSpeed",
         "tpdo2",
         {0x10, 0x27, 0x40, 0xE2, 0x01, 0x00},
         {{0x6004, 0, 0x2710, 100.0}, {0x6008, 0, 0x0001E240, 12.3456}}},
        // Reverse: -5000 = FFFF EC78h = -0.5 m/min.
        {"Tpdo2Reverse",
         "tpdo2",
         {0xF0, 0xD8, 0x78, 0xEC, 0xFF, 0xFF},
         {{0x6004, 0, 0xD8F0, -100.0}, {0x6008, 0, 0xFFFFEC78, -0.5}}},
        // Sent by the bridge, and read back in the monitor role from the controller's frame.
        {"Rpdo1ControlAndSpeedSetValue", "rpdo1", {0x42, 0x00, 0x2E, 0xFB}, kRpdo1},
        // A second control word may follow: 6 bytes carry 1234h.
        {"Rpdo1WithManufacturerControlWord", "rpdo1", {0x42, 0x00, 0x2E, 0xFB, 0x34, 0x12}, kRpdo1, {}, 0x1234},
    });

}  // namespace

INSTANTIATE_TEST_SUITE_P(Puller, ProfileFrame, ::testing::ValuesIn(kFrames), frame_name);

TEST_F(PullerProfile, Identity) {
  EXPECT_EQ(p_.device, "puller");
  EXPECT_EQ(p_.device_type, 0x01A4u);
  EXPECT_EQ(p30_.device, "puller");
  EXPECT_EQ(p30_.device_type, 0x01A4u);
}

TEST_F(PullerProfile, EveryObjectMatchesTheSpec) {
  // Section 3.1.1-3.1.14; every object is Mandatory.
  const std::vector<Variable> objects{
      {0x6000, "puller_speed_actual_value", DataType::integer16, Access::ro, "0.01 %", 0.01, "%", -10000, 10000},
      {0x6001, "puller_speed_real_maximum", DataType::unsigned32, Access::ro, "mm/min", 0.001, "m/min", none, none},
      {0x6002, "puller_speed_set_value", DataType::integer16, Access::rw, "0.01 %", 0.01, "%", -10000, 10000},
      {0x6003, "puller_speed_set_maximum", DataType::unsigned32, Access::rw, "mm/min", 0.001, "m/min", none, none},
      {0x6004, "puller_speed_set_echo", DataType::integer16, Access::ro, "0.01 %", 0.01, "%", -10000, 10000},
      {0x6005, "puller_speed_step", DataType::integer16, Access::rw, "0.01 %", 0.01, "%", -10000, 10000},
      {0x6006, "puller_load_actual_value", DataType::integer16, Access::ro, "0.01 %", 0.01, "%", -32768, 32767},
      {0x6007, "scaling_factor", DataType::unsigned32, Access::rw, "pulse/m", 1.0, "pulse/m", none, none},
      {0x6008, "product_speed", DataType::integer32, Access::ro, "0.1 mm/min", 0.0001, "m/min", 0, 10000},
      {0x6009, "height_adjustment", DataType::unsigned16, Access::rw, "0.1 mm", 0.0001, "m", none, none},
      {0x600A, "pressure_set_value", DataType::unsigned16, Access::rw, "0.01 %", 0.01, "%", 0, 10000},
      {0x6010, "configuration_word", DataType::unsigned32, Access::ro, "", 1.0, "", none, none},
      {0x6020, "control_word", DataType::unsigned16, Access::rw, "", 1.0, "", none, none},
      {0x6030, "status_word", DataType::unsigned16, Access::ro, "", 1.0, "", none, none},
  };
  EXPECT_EQ(p_.objects.size(), objects.size());
  expect_variables(p_, objects);
  // 3.1.8: FFFF FFFFh means "not configured"; any other value is a number of pulses per metre.
  const auto& scaling = p_.object(0x6007)->values;
  EXPECT_FALSE(scaling.exhaustive);
  EXPECT_EQ(scaling.name(0xFFFFFFFFu), "not_configured");
  EXPECT_TRUE(scaling.valid(10000));
  EXPECT_EQ(scaling.name(10000), std::nullopt);
}

TEST_F(PullerProfile, DefaultPdos) {
  // 2.1-2.3: TPDO1 180h, TPDO2 280h, RPDO1 200h (+ node-ID), transmission type 1.
  const Tail status{"manufacturer_status_word", 16};
  const Tail control{"manufacturer_control_word", 16};
  expect_pdos(p_, 5,
              {
                  {"tpdo1", PdoDirection::tx, 0x185, 1, PdoValidity::valid, true,
                   entries({0x60300010, 0x60000010, 0x60060010}), status},
                  // "1 mapped object", two listed
                  {"tpdo2", PdoDirection::tx, 0x285, 1, PdoValidity::valid, true, entries({0x60040010, 0x60080020})},
                  // lost table: as corrugator 3.1
                  {"rpdo1", PdoDirection::rx, 0x205, 1, PdoValidity::valid, true, entries({0x60200010, 0x60020010}),
                   control},
              });
}

TEST_F(PullerProfile, PrintedRanges) {
  // Product speed outside the printed 0..10000: decoded and published, flagged for diagnostics only.
  EXPECT_FALSE(p_.object(0x6008)->check_raw(123456));
  // The set value range is -10000..10000 (±100 %).
  const auto* set = p_.object(0x6002);
  EXPECT_TRUE(set->to_raw(-100.0));
  EXPECT_FALSE(set->to_raw(100.01));
  EXPECT_FALSE(set->to_raw(-100.01));
}

TEST_F(PullerProfile, ControlStatusAndConfigurationBits) {
  expect_bits(p_, "control_word", kControl);
  Bits status = kStatusShared;
  status.push_back({"reverse_direction", 7});
  expect_bits(p_, "status_word", status);
  expect_bits(p_, "configuration_word", {{"speed_measuring", 0}});
  EXPECT_EQ(p_.bitset("control_word")->index, 0x6020);
  EXPECT_EQ(p_.bitset("status_word")->index, 0x6030);
  EXPECT_EQ(p_.bitset("configuration_word")->index, 0x6010);
}

TEST_F(PullerProfile, Status30MovesReverseDirectionAndAddsSpeedSetMode) {
  Bits status = kStatusShared;
  status.push_back({"reverse_direction", 14});
  status.push_back({"speed_set_mode", 15});
  expect_bits(p30_, "status_word", status);
  const auto* mode = p30_.bitset("status_word")->field("speed_set_mode");
  ASSERT_NE(mode, nullptr);
  EXPECT_EQ(mode->values.name(0), "local");
  EXPECT_EQ(mode->values.name(1), "remote");

  // The same TPDO1 frame, status C080h: bits 15, 14 and 7.
  const std::array<std::uint8_t, 6> frame{0x80, 0xC0, 0x00, 0x00, 0x00, 0x00};
  Image v10(p_, "tpdo1");
  Image v30(p30_, "tpdo1");
  ASSERT_TRUE(v10.unpack(frame));
  ASSERT_TRUE(v30.unpack(frame));
  const auto* sw10 = p_.bitset("status_word");
  const auto* sw30 = p30_.bitset("status_word");
  // 1.0: bit 7 is reverse direction, 14 and 15 reserved.
  EXPECT_EQ(sw10->field("reverse_direction")->extract(v10.raw(0x6030)), 1u);
  EXPECT_EQ(sw10->field("speed_set_mode"), nullptr);
  // 3.0: bit 7 reserved, bit 14 reverse direction, bit 15 remote.
  EXPECT_EQ(sw30->field("reverse_direction")->extract(v30.raw(0x6030)), 1u);
  EXPECT_EQ(mode->values.name(mode->extract(v30.raw(0x6030))), "remote");
  const std::array<std::uint8_t, 6> only_bit7{0x80, 0x00, 0x00, 0x00, 0x00, 0x00};
  ASSERT_TRUE(v30.unpack(only_bit7));
  EXPECT_EQ(sw30->field("reverse_direction")->extract(v30.raw(0x6030)), 0u);
  EXPECT_EQ(mode->values.name(mode->extract(v30.raw(0x6030))), "local");
}

TEST_F(PullerProfile, Status30VariantDiffersOnlyInTheStatusWord) {
  ASSERT_EQ(p30_.objects.size(), p_.objects.size());
  for (std::size_t i = 0; i < p_.objects.size(); ++i) {
    const auto& a = p_.objects[i];
    const auto& b = p30_.objects[i];
    EXPECT_EQ(a.index, b.index);
    EXPECT_EQ(a.sub, b.sub);
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.type, b.type) << a.name;
    EXPECT_EQ(a.access, b.access) << a.name;
    EXPECT_EQ(a.unit, b.unit) << a.name;
    EXPECT_EQ(a.scale, b.scale) << a.name;
    EXPECT_EQ(a.eng_unit, b.eng_unit) << a.name;
    EXPECT_EQ(a.min, b.min) << a.name;
    EXPECT_EQ(a.max, b.max) << a.name;
    EXPECT_EQ(a.mandatory, b.mandatory) << a.name;
    EXPECT_EQ(a.values.ranges.size(), b.values.ranges.size()) << a.name;
  }
  ASSERT_EQ(p30_.pdos.size(), p_.pdos.size());
  for (std::size_t i = 0; i < p_.pdos.size(); ++i) {
    EXPECT_EQ(p_.pdos[i].name, p30_.pdos[i].name);
    EXPECT_EQ(p_.pdos[i].cob_id_base, p30_.pdos[i].cob_id_base);
    EXPECT_EQ(p_.pdos[i].transmission_type, p30_.pdos[i].transmission_type);
    EXPECT_EQ(p_.pdos[i].mapping, p30_.pdos[i].mapping);
    EXPECT_EQ(p_.pdos[i].manufacturer_data.has_value(), p30_.pdos[i].manufacturer_data.has_value());
  }
  expect_bits(p30_, "control_word", kControl);
  expect_bits(p30_, "configuration_word", {{"speed_measuring", 0}});
}
