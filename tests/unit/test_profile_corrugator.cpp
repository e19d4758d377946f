// Corrugator profile CiA 420-3 3.1.0 (spec file 003, tables 1-46) and profile-decisions.md (the
// bit layouts the text lost). Frames are written by hand (little-endian) and decoded by the
// production PDO codec; expected values are typed in.
#include <gtest/gtest.h>

#include <cstdint>
#include <optional>
#include <vector>

#include "support/profile_spec.hpp"

using namespace lb::test::spec;

namespace {

class CorrugatorProfile : public ::testing::Test {
 protected:
  lb::profiles::ProfileRegistry registry_ = lb::profiles::ProfileRegistry::builtin();
  const Profile& p_ = *registry_.find("cia420-3", "3.1");
};

// Status 4081h: drive running (0), master-extruder enabled (7), start cut pulse (14);
// speed 5000 = 1388h (50 %); load -1 = FFFFh (-0.01 %).
const std::vector<Value> kTpdo1{{0x6030, 0, 0x4081}, {0x6000, 0, 0x1388, 50.0}, {0x6006, 0, 0xFFFF, -0.01}};
const std::vector<Flag> kTpdo1Flags{{"status_word", "drive_running", 1},
                                    {"status_word", "master_extruder_enabled", 1},
                                    {"status_word", "start_cut_pulse", 1},
                                    {"status_word", "fault", 0}};

const auto kFrames =
    frames_of("cia420-3", "3.1",
              {
                  {"Tpdo1StatusSpeedAndLoad", "tpdo1", {0x81, 0x40, 0x88, 0x13, 0xFF, 0xFF}, kTpdo1, kTpdo1Flags},
                  {"Tpdo1WithManufacturerStatusWord",
                   "tpdo1",
                   {0x81, 0x40, 0x88, 0x13, 0xFF, 0xFF, 0x01, 0x80},
                   kTpdo1,
                   kTpdo1Flags,
                   0x8001},
                  // Echo -10000 = D8F0h (-100 %); product speed -123456 = FFFE 1DC0h in 0.1 mm/min = -12.3456 m/min.
                  {"Tpdo2EchoAndProductSpeed",
                   "tpdo2",
                   {0xF0, 0xD8, 0xC0, 0x1D, 0xFE, 0xFF},
                   {{0x6004, 0, 0xD8F0, -100.0}, {0x6008, 0, 0xFFFE1DC0, -12.3456}}},
                  // Control 0406h: drive start (1), move in (2), f2 start (10); 75.5 % = 7550 = 1D7Eh. Sent by the
                  // bridge, and read back in the monitor role.
                  {"Rpdo1ControlAndSpeedSetValue",
                   "rpdo1",
                   {0x06, 0x04, 0x7E, 0x1D},
                   {{0x6020, 0, 0x0406}, {0x6002, 0, 0x1D7E, 75.5}}},
              });

}  // namespace

INSTANTIATE_TEST_SUITE_P(Corrugator, ProfileFrame, ::testing::ValuesIn(kFrames), frame_name);

TEST_F(CorrugatorProfile, Identity) {
  EXPECT_EQ(p_.device, "corrugator");
  EXPECT_EQ(p_.device_type, 0x01A4u);
}

TEST_F(CorrugatorProfile, EveryVariableMatchesTheSpec) {
  // Tables 14-31 and 39-46: all Mandatory VARs.
  const std::vector<Variable> objects{
      {0x6000, "corrugator_speed_actual_value", DataType::integer16, Access::ro, "0.01 %", 0.01, "%", -10000, 10000},
      {0x6001, "corrugator_speed_real_maximum", DataType::unsigned32, Access::const_, "mm/min", 0.001, "m/min", none,
       none},
      {0x6002, "corrugator_speed_set_value", DataType::integer16, Access::rw, "0.01 %", 0.01, "%", -10000, 10000},
      {0x6003, "corrugator_speed_set_maximum", DataType::unsigned32, Access::rw, "mm/min", 0.001, "m/min", none, none},
      {0x6004, "corrugator_speed_set_echo", DataType::integer16, Access::ro, "0.01 %", 0.01, "%", -10000, 10000},
      {0x6005, "corrugator_speed_step", DataType::unsigned16, Access::rw, "0.01 %", 0.01, "%", 0, 10000},
      {0x6006, "corrugator_load_actual_value", DataType::integer16, Access::ro, "0.01 %", 0.01, "%", none, none},
      {0x6007, "scaling_factor", DataType::unsigned32, Access::rw, "pulse/m", 1.0, "pulse/m", none, none},
      {0x6008, "product_speed", DataType::integer32, Access::ro, "0.1 mm/min", 0.0001, "m/min", none, none},
      {0x6010, "configuration_word", DataType::unsigned32, Access::ro, "", 1.0, "", none, none},
      {0x6020, "control_word", DataType::unsigned16, Access::rw, "", 1.0, "", none, none},
      {0x6030, "status_word", DataType::unsigned16, Access::ro, "", 1.0, "", none, none},
  };
  expect_variables(p_, objects);
  // Unlike the puller 1.0, 6007h has no "not configured" code in 3.1.
  EXPECT_TRUE(p_.object(0x6007)->values.empty());
  // 12 VARs and 3 optional ARRAYs of 10 elements + sub 0.
  EXPECT_EQ(p_.objects.size(), 12u + 3u * 11u);
}

TEST_F(CorrugatorProfile, ArraysOfTenElements) {
  // Tables 32-37: Optional ARRAYs, sub 0 const (highest sub-index 01h..0Ah), subs 01h..0Ah.
  expect_arrays(p_,
                {
                    {0x6009, "height_adjustment", DataType::integer16, Access::rw, "0.1 mm", 0.0001, "m", none, none},
                    {0x600A, "pressure_set_value", DataType::unsigned16, Access::rw, "0.01 %", 0.01, "%", 0, 10000},
                    {0x600B, "actual_temperature", DataType::integer16, Access::ro, "0.1 °C", 0.1, "°C", -2732, 32767},
                },
                10);
}

TEST_F(CorrugatorProfile, ScalingOfArrayValues) {
  // 600Bh in 0.1 °C: -2732 = F554h is absolute zero; -200 = FF38h is -20.0 °C.
  const auto* t = p_.object(0x600B, 3);
  EXPECT_DOUBLE_EQ(t->to_engineering(0xF554), -273.2);
  EXPECT_DOUBLE_EQ(t->to_engineering(0xFF38), -20.0);
  EXPECT_DOUBLE_EQ(t->to_engineering(0x7FFF), 3276.7);
  EXPECT_FALSE(t->check_raw(-2733));
  // 6009h: negative is below the centre line: -1500 = FA24h = -0.15 m.
  EXPECT_DOUBLE_EQ(p_.object(0x6009, 1)->to_engineering(0xFA24), -0.15);
  // 600Ah: 0..10000 (0..100 %).
  EXPECT_FALSE(p_.object(0x600A, 2)->to_raw(100.01));
  EXPECT_EQ(*p_.object(0x600A, 2)->to_raw(45.5), 4550u);
}

TEST_F(CorrugatorProfile, DefaultPdos) {
  // Tables 1-13: TPDO1 4000 0180h, TPDO2 4000 0280h, RPDO1 4000 0200h (+ node-ID), type 01h.
  // Table 1 note: TPDO1 and RPDO1 may carry one manufacturer-specific object.
  expect_pdos(p_, 0x12,
              {
                  {"tpdo1", PdoDirection::tx, 0x192, 1, PdoValidity::valid, true,
                   entries({0x60300010, 0x60000010, 0x60060010}), Tail{"manufacturer_status_word", 16}},
                  {"tpdo2", PdoDirection::tx, 0x292, 1, PdoValidity::valid, true, entries({0x60040010, 0x60080020})},
                  {"rpdo1", PdoDirection::rx, 0x212, 1, PdoValidity::valid, true, entries({0x60200010, 0x60020010}),
                   Tail{"manufacturer_control_word", 16}},
              });
}

TEST_F(CorrugatorProfile, Rpdo1ValuesFromNamesAndPercent) {
  // Control 0406h from the names drive start (1), move in (2), f2 start (10); 75.5 % = 7550.
  const auto* cw = p_.bitset("control_word");
  std::uint64_t word = 0;
  for (const char* name : {"drive_start", "move_in", "f2_start"}) word = cw->field(name)->insert(word, 1);
  EXPECT_EQ(word, 0x0406u);
  const auto* set = p_.object(0x6002);
  const auto raw = set->to_raw(75.5);
  ASSERT_TRUE(raw);
  EXPECT_EQ(*raw, 7550u);
  EXPECT_FALSE(set->to_raw(-100.01));
}

TEST_F(CorrugatorProfile, ControlStatusAndConfigurationBits) {
  expect_bits(p_, "control_word",
              {{"drive_stop", 0},
               {"drive_start", 1},
               {"move_in", 2},
               {"move_out", 3},
               {"extruder_running", 6},
               {"f1_stop", 7},
               {"f1_start", 8},
               {"f2_stop", 9},
               {"f2_start", 10},
               {"f3_stop", 11},
               {"f3_start", 12}});
  expect_bits(p_, "status_word",
              {{"drive_running", 0},
               {"drive_ready_to_start", 1},
               {"fault", 3},
               {"alarm", 4},
               {"increase_request", 5},
               {"decrease_request", 6},
               {"master_extruder_enabled", 7},
               {"f1_running", 8},
               {"f1_ready", 9},
               {"f2_running", 10},
               {"f2_ready", 11},
               {"f3_running", 12},
               {"f3_ready", 13},
               {"start_cut_pulse", 14}});
  expect_bits(p_, "configuration_word",
              {{"speed_measuring", 0},
               {"height_adjustment", 1},
               {"pressure_set_values", 2},
               {"actual_temperatures", 3},
               {"f1_available", 4},
               {"f2_available", 5},
               {"f3_available", 6}});
  EXPECT_EQ(p_.bitset("control_word")->index, 0x6020);
  EXPECT_EQ(p_.bitset("status_word")->index, 0x6030);
  EXPECT_EQ(p_.bitset("configuration_word")->index, 0x6010);
}
