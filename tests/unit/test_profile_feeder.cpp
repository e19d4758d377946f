// Feeder profile CiA 414-2 1.1.0 (spec file 000, sections 4 and 5) and profile-decisions.md (the
// 6001h and 6003h/6004h layouts the text lost). Frames and words are written by hand
// (little-endian) and decoded by the production PDO codec; expected values and code names are
// typed in from the specification's tables.
#include <gtest/gtest.h>

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "support/profile_spec.hpp"

using lb::profiles::ValueTable;
using namespace lb::test::spec;

namespace {

using Codes = std::vector<std::pair<std::uint64_t, const char*>>;

// Every listed code has its name, and exactly the listed codes are valid among 0..max.
void expect_enumeration(const ValueTable& table, const Codes& codes, std::uint64_t max, const char* what) {
  EXPECT_TRUE(table.exhaustive) << what;
  for (const auto& [code, name] : codes) EXPECT_EQ(table.name(code), name) << what << " code " << code;
  std::size_t valid = 0;
  for (std::uint64_t c = 0; c <= max; ++c) valid += table.valid(c) ? 1 : 0;
  EXPECT_EQ(valid, codes.size()) << what << ": codes beyond the table must be invalid";
}

class FeederProfile : public ::testing::Test {
 protected:
  lb::profiles::ProfileRegistry registry_ = lb::profiles::ProfileRegistry::builtin();
  const Profile& p_ = *registry_.find("cia414-2", "1.1");
};

const auto kFrames = frames_of(
    "cia414-2", "1.1",
    {
        // Empty, single colour 5, single colour 16, double 3+1, triple 3/5/7; as loom controller the
        // same bytes back.
        {"Rpdo1FivePicks",
         "rpdo1",
         {0x00, 0x05, 0x10, 0x31, 0x33},
         {{0x600C, 1, 0x00, std::nullopt, "empty_pick"},
          {0x600C, 2, 0x05, std::nullopt, "single_pick"},
          {0x600C, 3, 0x10, std::nullopt, "single_pick"},
          {0x600C, 4, 0x31, std::nullopt, "double_pick"},
          {0x600C, 5, 0x33, std::nullopt, "triple_pick"}}},
        // A reserved code is carried raw and reported invalid, never guessed.
        {"Rpdo1ReservedPickIsCarriedRaw",
         "rpdo1",
         {0xDD, 0x00, 0x00, 0x00, 0x00},
         {{0x600C, 1, 0xDD, std::nullopt, kInvalidCode},
          {0x600C, 2, 0x00},
          {0x600C, 3, 0x00},
          {0x600C, 4, 0x00},
          {0x600C, 5, 0x00}}},
        {"Rpdo1ShortFrameIsRefused", "rpdo1", {0x00, 0x05, 0x10, 0x31}, {}, {}, std::nullopt, true},
        {"Rpdo3DigitalOutputs",
         "rpdo3",
         {0x01, 0x02, 0x04, 0x08, 0x10, 0x20, 0x40, 0x80},
         {{0x600D, 1, 0x01},
          {0x600D, 2, 0x02},
          {0x600D, 3, 0x04},
          {0x600D, 4, 0x08},
          {0x600D, 5, 0x10},
          {0x600D, 6, 0x20},
          {0x600D, 7, 0x40},
          {0x600D, 8, 0x80}}},
        {"Rpdo4TriggerSignal", "rpdo4", {0x04}, {{0x600B, 0, 0x04, std::nullopt, "brush_do_release"}}},
        {"Rpdo4FutureTriggerSignalIsInvalid", "rpdo4", {0x05}, {{0x600B, 0, 0x05, std::nullopt, kInvalidCode}}},
    });

}  // namespace

INSTANTIATE_TEST_SUITE_P(Feeder, ProfileFrame, ::testing::ValuesIn(kFrames), frame_name);

TEST_F(FeederProfile, Identity) {
  EXPECT_EQ(p_.device, "feeder");
  EXPECT_EQ(p_.device_type, 0x019Eu);  // 414
}

namespace {

// An object (or, for an array, its sub 0) as the specification tables list it.
struct SpecObject {
  std::uint16_t index;
  std::uint8_t sub;
  const char* name;
  DataType type;
  Access access;
  bool mandatory;
};

}  // namespace

TEST_F(FeederProfile, VariablesAndNamedSubsMatchTheSpec) {
  // Sections 5.2.1-5.2.19; conditional objects count as not mandatory.
  const std::vector<SpecObject> objects{
      {0x6000, 0, "brush_release_count", DataType::unsigned8, Access::ro, false},
      {0x6000, 1, "brush_release_opening_delay_time", DataType::unsigned16, Access::ro, false},
      {0x6000, 2, "brush_release_closing_delay_time", DataType::unsigned16, Access::ro, false},
      {0x6002, 0, "weft_insertion_type_parameter", DataType::unsigned8, Access::wo, true},
      {0x6004, 0, "global_weft_filling_parameter", DataType::unsigned32, Access::wo, true},
      {0x6005, 0, "trigger_signal_source_count", DataType::unsigned8, Access::ro, true},
      {0x6005, 1, "trigger_sources_supported", DataType::unsigned16, Access::ro, true},
      {0x6005, 2, "trigger_sources_selected", DataType::unsigned16, Access::rw, true},
      {0x6006, 0, "angle_trigger_timeout", DataType::unsigned16, Access::rw, false},
      {0x6008, 0, "feeder_control_box_error_condition", DataType::unsigned8, Access::ro, false},
      {0x600A, 0, "loom_status", DataType::unsigned8, Access::wo, true},
      {0x600B, 0, "trigger_signal", DataType::unsigned8, Access::wo, true},
      {0x600C, 0, "pick_insertion_count", DataType::unsigned8, Access::ro, true},
      {0x600C, 1, "pick_insertion_1", DataType::unsigned8, Access::wo, true},
      {0x600C, 2, "pick_insertion_2", DataType::unsigned8, Access::wo, true},
      {0x600C, 3, "pick_insertion_3", DataType::unsigned8, Access::wo, true},
      {0x600C, 4, "pick_insertion_4", DataType::unsigned8, Access::wo, true},
      {0x600C, 5, "pick_insertion_5", DataType::unsigned8, Access::wo, true},
      {0x6010, 0, "feeder_unwinding_time", DataType::unsigned32, Access::ro, true},
  };
  for (const auto& e : objects) {
    const auto* o = p_.object(e.index, e.sub);
    ASSERT_NE(o, nullptr) << std::hex << e.index << " sub " << int{e.sub};
    EXPECT_EQ(o->name, e.name);
    EXPECT_EQ(o->type, e.type) << e.name;
    EXPECT_EQ(o->access, e.access) << e.name;
    EXPECT_EQ(o->mandatory, e.mandatory) << e.name;
  }
  EXPECT_EQ(p_.object(0x6000, 3), nullptr);
  EXPECT_EQ(p_.object(0x6005, 3), nullptr);
  EXPECT_EQ(p_.object(0x600C, 6), nullptr);
  // Units: delays in 0.1 ms, the timeout in ms.
  EXPECT_EQ(p_.object(0x6000, 1)->unit, "0.1 ms");
  EXPECT_DOUBLE_EQ(p_.object(0x6000, 2)->to_engineering(25), 2.5);
  EXPECT_EQ(p_.object(0x6000, 2)->eng_unit, "ms");
  EXPECT_EQ(p_.object(0x6006)->unit, "ms");
  EXPECT_DOUBLE_EQ(p_.object(0x6006)->to_engineering(500), 500.0);
  // 6006h = 0: not configured, no PDOs processed; any other value is a time.
  EXPECT_FALSE(p_.object(0x6006)->values.exhaustive);
  EXPECT_EQ(p_.object(0x6006)->values.name(0), "not_configured");
  EXPECT_TRUE(p_.object(0x6006)->values.valid(300));
}

TEST_F(FeederProfile, PerFeederArraysHave254Elements) {
  // The arrays (sub 0: their count). Sub-index n = feeder n, 01h..FEh; sub 1 is mandatory (with a mandatory object),
  // the rest optional.
  const std::vector<SpecObject> arrays{
      {0x6001, 0, "feeder_functions", DataType::unsigned32, Access::rw, true},
      {0x6003, 0, "single_weft_filling_parameter", DataType::unsigned32, Access::wo, false},
      {0x6007, 0, "feeder_error_condition", DataType::unsigned8, Access::ro, false},
      {0x6009, 0, "feeder_status", DataType::unsigned8, Access::ro, true},
      {0x600E, 0, "feeder_command", DataType::unsigned8, Access::wo, true},
      {0x600F, 0, "feeder_test", DataType::unsigned16, Access::rw, false},
      {0x6011, 0, "system_feeder_number_assignment", DataType::unsigned8, Access::rw, false},
      {0x6012, 0, "feeder_color_assignment", DataType::unsigned8, Access::rw, false},
  };
  for (const auto& e : arrays) {
    const auto* count = p_.object(e.index, 0);
    ASSERT_NE(count, nullptr) << e.name;
    EXPECT_EQ(count->type, DataType::unsigned8) << e.name;
    EXPECT_FALSE(count->writable()) << e.name;
    EXPECT_EQ(count->mandatory, e.mandatory) << e.name;
    for (unsigned feeder : {1U, 2U, 32U, 33U, 254U}) {
      const auto* o = p_.object(e.index, static_cast<std::uint8_t>(feeder));
      ASSERT_NE(o, nullptr) << e.name << " feeder " << feeder;
      EXPECT_EQ(o->name, std::string(e.name) + "_" + std::to_string(feeder));
      EXPECT_EQ(o->type, e.type) << o->name;
      EXPECT_EQ(o->access, e.access) << o->name;
      EXPECT_EQ(o->mandatory, e.mandatory && feeder == 1) << o->name;
    }
    EXPECT_EQ(p_.object(e.index, 255), nullptr) << e.name;
  }
  // 600Dh: 8 output groups, group 1 mandatory.
  for (std::uint8_t group = 1; group <= 8; ++group) {
    const auto* o = p_.object(0x600D, group);
    ASSERT_NE(o, nullptr);
    EXPECT_EQ(o->type, DataType::unsigned8);
    EXPECT_EQ(o->access, Access::rw);
    EXPECT_EQ(o->mandatory, group == 1);
  }
  EXPECT_EQ(p_.object(0x600D, 9), nullptr);
}

TEST_F(FeederProfile, EnumerationsAndReservedCodes) {
  expect_enumeration(p_.object(0x6002)->values,
                     {{0, "do_not_process_pdos"}, {1, "projectile"}, {2, "rapier"}, {3, "air_jet"}, {4, "water_jet"}},
                     0xFF, "6002h");
  expect_enumeration(p_.object(0x6007, 17)->values,
                     {{0x00, "no_error"},
                      {0x01, "no_settings_in_eeprom"},
                      {0x02, "on_off_switch_off"},
                      {0x03, "weaving_machine_parameter_missing"},
                      {0x04, "yarn_broken"},
                      {0x05, "pre_winder_running_empty"},
                      {0x06, "temperature_too_high"},
                      {0x07, "motor_voltage_not_ok"},
                      {0x08, "no_eeprom_communication"},
                      {0x09, "rotation_not_possible"},
                      {0x0A, "filling_up_failed"},
                      {0x0B, "color_information_missing"},
                      {0x0C, "angle_trigger_signal_missing"},
                      {0x0D, "tks_event"},
                      {0x0E, "knot_detected"},
                      {0x0F, "general_error"}},
                     0xFF, "6007h");
  // 6008h: 02h, 04h, 05h, 09h, 0Ah, 0Dh, 0Eh are reserved between the defined codes.
  expect_enumeration(p_.object(0x6008)->values,
                     {{0x00, "no_error"},
                      {0x01, "no_settings_in_eeprom"},
                      {0x03, "weaving_machine_parameter_missing"},
                      {0x06, "temperature_too_high"},
                      {0x07, "motor_voltage_not_ok"},
                      {0x08, "no_eeprom_communication"},
                      {0x0B, "color_information_missing"},
                      {0x0C, "angle_trigger_signal_missing"},
                      {0x0F, "general_error"}},
                     0xFF, "6008h");
  EXPECT_FALSE(p_.object(0x6008)->values.valid(0x02));
  EXPECT_FALSE(p_.object(0x6008)->values.valid(0x0E));
  expect_enumeration(p_.object(0x6009, 254)->values,
                     {{0, "operational_mode"},
                      {1, "positioning_mode"},
                      {2, "filling_up_to_maximum_sensor"},
                      {3, "pcat_test_mode"},
                      {4, "non_operational_mode"},
                      {5, "not_present"},
                      {6, "initializing_mode"},
                      {7, "error_mode"}},
                     0xFF, "6009h");
  expect_enumeration(p_.object(0x600A)->values,
                     {{0, "stop"},
                      {1, "start_advice"},
                      {2, "new_speed_only"},
                      {3, "slow_motion_forward"},
                      {4, "slow_motion_backward"}},
                     0xFF, "600Ah");
  expect_enumeration(p_.object(0x600B)->values,
                     {{0, "no_signal"},
                      {1, "angle_trigger"},
                      {2, "pick_release_trigger"},
                      {3, "brush_do_not_release"},
                      {4, "brush_do_release"}},
                     0xFF, "600Bh");
  // 600Eh: 09h..5Fh manufacturer-specific (valid, meaning device-defined), 60h..FFh reserved.
  const auto& command = p_.object(0x600E, 5)->values;
  const Codes commands{{0x00, "non_operation_mode"},
                       {0x01, "operation_mode"},
                       {0x02, "start"},
                       {0x03, "stop_mode"},
                       {0x04, "reset"},
                       {0x05, "led_on"},
                       {0x06, "led_off"},
                       {0x07, "open_pin"},
                       {0x08, "close_pin"}};
  for (const auto& [code, name] : commands) {
    EXPECT_EQ(command.name(code), name);
    EXPECT_EQ(command.code(name), code) << name;  // the bridge sends commands by name
  }
  EXPECT_EQ(command.name(0x09), "manufacturer_specific");
  EXPECT_EQ(command.name(0x5F), "manufacturer_specific");
  EXPECT_EQ(command.code("manufacturer_specific"), std::nullopt);
  EXPECT_FALSE(command.valid(0x60));
  EXPECT_FALSE(command.valid(0xFF));
}

TEST_F(FeederProfile, PickInsertionCodes) {
  const auto& picks = p_.object(0x600C, 1)->values;
  const Codes codes{
      {0x00, "empty_pick"},  {0x01, "single_pick"}, {0x0F, "single_pick"}, {0x10, "single_pick"},  // 10h: colour 16
      {0x11, "triple_pick"}, {0x21, "double_pick"}, {0x22, "triple_pick"}, {0x32, "double_pick"},
      {0x87, "double_pick"}, {0xCB, "double_pick"}, {0xCC, "triple_pick"}, {0xDC, "double_pick"},
      {0xED, "double_pick"}, {0xF1, "double_pick"}, {0xFE, "double_pick"},
  };
  for (const auto& [code, name] : codes) EXPECT_EQ(picks.name(code), name) << "code " << code;
  // Reserved (DDh, EEh, FFh), in no row (H0h, H >= 2), kept free (0 < H < L).
  for (std::uint64_t code : {0xDD, 0xEE, 0xFF, 0x20, 0xF0, 0x12, 0x1F, 0x5A, 0xEF}) {
    EXPECT_FALSE(picks.valid(code)) << "code " << code;
  }
  // 1 empty + 16 single + 105 double (H > L >= 1) + 12 triple (11h..CCh) = 134 valid codes.
  std::size_t valid = 0;
  for (std::uint64_t c = 0; c <= 0xFF; ++c) valid += picks.valid(c) ? 1 : 0;
  EXPECT_EQ(valid, 134u);
  for (std::uint8_t sub = 2; sub <= 5; ++sub) {
    EXPECT_EQ(p_.object(0x600C, sub)->values.ranges.size(), picks.ranges.size()) << int{sub};
  }
}

TEST_F(FeederProfile, DefaultPdos) {
  // 4.2-4.6: every PDO event-driven, transmission type 255; cob_ids for node 10.
  expect_pdos(p_, 10,
              {
                  {"rpdo1", PdoDirection::rx, 0x20A, 255, PdoValidity::valid, true,
                   entries({0x600C0108, 0x600C0208, 0x600C0308, 0x600C0408, 0x600C0508})},
                  {"rpdo2", PdoDirection::rx, 0x30A, 255, PdoValidity::valid, true, entries({0x600A0008, 0x60040020})},
                  {"rpdo3", PdoDirection::rx, 0x40A, 255, PdoValidity::valid, false,
                   entries({0x600D0108, 0x600D0208, 0x600D0308, 0x600D0408, 0x600D0508, 0x600D0608, 0x600D0708,
                            0x600D0808})},
                  {"rpdo4", PdoDirection::rx, 0x50A, 255, PdoValidity::valid, false, entries({0x600B0008})},
                  // {C000 0180h, 4000 0180h} + node-ID: may be disabled; a silent TPDO1 is no fault.
                  {"tpdo1", PdoDirection::tx, 0x18A, 255, PdoValidity::either, true, entries({0x60100020})},
              });
}

TEST_F(FeederProfile, Rpdo2LoomStatusAndGlobalWeftFilling) {
  // Loom status 1 (start advice); 6004h = 00BE 0258h: loom width 190 cm (BEh), max speed 600/min (258h).
  Image img(p_, "rpdo2");
  const std::array<std::uint8_t, 5> frame{0x01, 0x58, 0x02, 0xBE, 0x00};
  ASSERT_TRUE(img.unpack(frame));
  EXPECT_EQ(p_.object(0x600A)->values.name(img.raw(0x600A)), "start_advice");
  const auto word = img.raw(0x6004);
  EXPECT_EQ(word, 0x00BE0258u);
  const auto* fields = p_.bitset("global_weft_filling_parameter");
  ASSERT_NE(fields, nullptr);
  EXPECT_TRUE(fields->applies_to(0x6004, 0));
  EXPECT_EQ(fields->field("maximum_speed")->extract(word), 600u);
  EXPECT_EQ(fields->field("maximum_speed")->unit, "1/min");
  EXPECT_EQ(fields->field("loom_width")->extract(word), 190u);
  EXPECT_DOUBLE_EQ(fields->field("loom_width")->to_engineering(190), 1.9);
  EXPECT_EQ(fields->field("loom_width")->eng_unit, "m");
  // As loom controller: status "new speed only" (2), 720/min, 340 cm = 0154 02D0h.
  std::uint64_t filling = fields->field("maximum_speed")->insert(0, 720);
  filling = fields->field("loom_width")->insert(filling, 340);
  img.set(0x600A, 0, *p_.object(0x600A)->values.code("new_speed_only"));
  img.set(0x6004, 0, filling);
  EXPECT_EQ(img.pack(), (std::vector<std::uint8_t>{0x02, 0xD0, 0x02, 0x54, 0x01}));
}

TEST_F(FeederProfile, SingleWeftFillingHasTheGlobalLayoutPerFeeder) {
  const auto* single = p_.bitset("single_weft_filling_parameter");
  const auto* global = p_.bitset("global_weft_filling_parameter");
  ASSERT_TRUE(single && global);
  EXPECT_TRUE(single->every_element);
  EXPECT_TRUE(single->applies_to(0x6003, 1));
  EXPECT_TRUE(single->applies_to(0x6003, 254));
  EXPECT_FALSE(single->applies_to(0x6003, 0));
  for (const char* name : {"maximum_speed", "loom_width"}) {
    EXPECT_EQ(single->field(name)->bit, global->field(name)->bit) << name;
    EXPECT_EQ(single->field(name)->width, 16u) << name;
  }
  EXPECT_EQ(single->field("maximum_speed")->bit, 0u);
  EXPECT_EQ(single->field("loom_width")->bit, 16u);
}

TEST_F(FeederProfile, Tpdo1UnwindingTime) {
  // Feeder 3, winding 7, 98.7 ms = 987 = 03DBh: 0307 03DBh.
  Image img(p_, "tpdo1");
  const std::array<std::uint8_t, 4> frame{0xDB, 0x03, 0x07, 0x03};
  ASSERT_TRUE(img.unpack(frame));
  const auto word = img.raw(0x6010);
  EXPECT_EQ(word, 0x030703DBu);
  const auto* t = p_.bitset("feeder_unwinding_time");
  ASSERT_NE(t, nullptr);
  const auto* feeder = t->field("feeder_selected");
  const auto* winding = t->field("winding_number");
  const auto* time = t->field("coil_unwinding_time");
  ASSERT_TRUE(feeder && winding && time);
  EXPECT_EQ(feeder->bit, 24u);
  EXPECT_EQ(feeder->width, 8u);
  EXPECT_EQ(winding->bit, 16u);
  EXPECT_EQ(winding->width, 8u);
  EXPECT_EQ(time->bit, 0u);
  EXPECT_EQ(time->width, 16u);
  EXPECT_EQ(feeder->extract(word), 3u);
  EXPECT_EQ(winding->extract(word), 7u);
  EXPECT_EQ(time->extract(word), 987u);
  EXPECT_DOUBLE_EQ(time->to_engineering(time->extract(word)), 98.7);
  EXPECT_EQ(time->eng_unit, "ms");
  EXPECT_TRUE(feeder->in_range(3) && winding->in_range(7) && time->in_range(987));
  // Printed ranges: feeder 01h..FEh, winding 1..50, time 0..1000; beyond them: decoded, flagged.
  const std::array<std::uint8_t, 4> odd{0xE9, 0x03, 0x33, 0xFF};  // FF33 03E9h: feeder 255, winding 51, 1001
  ASSERT_TRUE(img.unpack(odd));
  EXPECT_EQ(feeder->extract(img.raw(0x6010)), 255u);
  EXPECT_FALSE(feeder->in_range(255));
  EXPECT_FALSE(winding->in_range(winding->extract(img.raw(0x6010))));
  EXPECT_FALSE(time->in_range(time->extract(img.raw(0x6010))));
  EXPECT_TRUE(time->in_range(1000));
}

TEST_F(FeederProfile, FeederFunctionsTwoBitFields) {
  const auto* f = p_.bitset("feeder_functions");
  ASSERT_NE(f, nullptr);
  EXPECT_TRUE(f->every_element);
  EXPECT_TRUE(f->applies_to(0x6001, 1));
  EXPECT_TRUE(f->applies_to(0x6001, 254));
  struct Field {
    const char* name;
    unsigned bit;
  };
  // profile-decisions.md (reading): BR 31-30, WD 29-28, AT 27-26, YB 13-12, IKD 11-10, YQ 9-8, RD 7-6, TKS 5-4.
  const std::vector<Field> layout{{"brush_release", 30},
                                  {"winding_direction", 28},
                                  {"angle_trigger_monitoring", 26},
                                  {"yarn_break_sensor", 12},
                                  {"input_knot_detection_sensor", 10},
                                  {"yarn_quality_sensor", 8},
                                  {"rotation_direction_sensor", 6},
                                  {"tks_sensor", 4}};
  EXPECT_EQ(f->bits.size(), layout.size());
  for (const auto& e : layout) {
    const auto* field = f->field(e.name);
    ASSERT_NE(field, nullptr) << e.name;
    EXPECT_EQ(field->bit, e.bit) << e.name;
    EXPECT_EQ(field->width, 2u) << e.name;
    EXPECT_EQ(f->bit(e.name), std::nullopt) << e.name << " is no flag";
  }
  // F800 32E0h: BR 11 on, WD 11 Z, AT 10 off, YB 11 active, IKD 00 not available, YQ 10 not active,
  // RD 11 active, TKS 10 not active.
  const std::uint64_t word = 0xF80032E0;
  const std::vector<std::pair<const char*, const char*>> decoded{{"brush_release", "on"},
                                                                 {"winding_direction", "z"},
                                                                 {"angle_trigger_monitoring", "off"},
                                                                 {"yarn_break_sensor", "active"},
                                                                 {"input_knot_detection_sensor", "not_available"},
                                                                 {"yarn_quality_sensor", "not_active"},
                                                                 {"rotation_direction_sensor", "active"},
                                                                 {"tks_sensor", "not_active"}};
  for (const auto& [name, value] : decoded) {
    const auto* field = f->field(name);
    EXPECT_EQ(field->values.name(field->extract(word)), value) << name;
  }
  // 01b is undefined everywhere; WD has no "not available".
  const auto* wd = f->field("winding_direction");
  EXPECT_EQ(wd->values.name(0b10), "s");
  EXPECT_FALSE(wd->values.valid(0b00));
  EXPECT_FALSE(f->field("brush_release")->values.valid(0b01));
  EXPECT_FALSE(f->field("tks_sensor")->values.valid(0b01));
  // Switching a sensor on by name.
  const auto* yb = f->field("yarn_break_sensor");
  EXPECT_EQ(yb->insert(0, *yb->values.code("active")), 0x3000u);
}

TEST_F(FeederProfile, TriggerSignalSourceBits) {
  const Bits bits{{"brush_release_via_canopen", 0},        {"brush_release_via_parallel_line", 1},
                  {"angle_trigger_via_canopen", 4},        {"angle_trigger_via_parallel_line", 5},
                  {"pick_release_trigger_via_canopen", 8}, {"pick_release_trigger_via_parallel_line", 9}};
  const auto* supported = p_.bitset("trigger_sources_supported");
  const auto* selected = p_.bitset("trigger_sources_selected");
  ASSERT_TRUE(supported && selected);
  EXPECT_TRUE(supported->applies_to(0x6005, 1));
  EXPECT_FALSE(supported->applies_to(0x6005, 2));
  EXPECT_TRUE(selected->applies_to(0x6005, 2));
  for (const auto* set : {supported, selected}) {
    EXPECT_EQ(set->bits.size(), bits.size()) << set->name;
    for (const auto& [name, bit] : bits) EXPECT_EQ(set->bit(name), bit) << set->name << "." << name;
  }
  // Default of sub 2, 01h: brush-release signal via CANopen only.
  EXPECT_EQ(selected->field("brush_release_via_canopen")->extract(0x01), 1u);
  EXPECT_EQ(selected->field("angle_trigger_via_canopen")->extract(0x01), 0u);
}

TEST_F(FeederProfile, FeederTestCodeAndParameter) {
  const auto* t = p_.bitset("feeder_test");
  ASSERT_NE(t, nullptr);
  EXPECT_TRUE(t->every_element);
  const auto* code = t->field("test_code");
  const auto* parameter = t->field("test_parameter");
  ASSERT_TRUE(code && parameter);
  // (reading) code in bits 15-8, parameter in bits 7-0: 0132h = motor test at 50 Hz.
  EXPECT_EQ(code->bit, 8u);
  EXPECT_EQ(code->width, 8u);
  EXPECT_EQ(parameter->bit, 0u);
  EXPECT_EQ(parameter->width, 8u);
  EXPECT_EQ(code->values.name(code->extract(0x0132)), "motor_test");
  EXPECT_EQ(parameter->extract(0x0132), 50u);
  expect_enumeration(code->values, {{0, "no_test"}, {1, "motor_test"}, {2, "pin_test"}, {3, "strobo_function"}}, 0xFF,
                     "600Fh test code");
}
