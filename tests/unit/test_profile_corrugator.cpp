// Corrugator profile CiA 420-3 3.1.0 (spec file 003, tables 1-46) and profile-decisions.md (the
// bit layouts the text lost). Frames are written by hand (little-endian) and decoded by the
// production PDO codec; expected values are typed in.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "canopen/pdo_mapping.hpp"
#include "profiles/profile_registry.hpp"
#include "support/profile_image.hpp"

using lb::canopen::DataType;
using lb::canopen::PdoEntry;
using lb::profiles::Access;
using lb::profiles::PdoDirection;
using lb::profiles::PdoValidity;
using lb::profiles::Profile;
using lb::test::entries;
using lb::test::Image;
using lb::test::Bits;
using lb::test::expect_bits;

namespace {

class CorrugatorProfile : public ::testing::Test {
 protected:
  lb::profiles::ProfileRegistry registry_ = lb::profiles::ProfileRegistry::builtin();
  const Profile& p_ = *registry_.find("cia420-3", "3.1");
};

}  // namespace

TEST_F(CorrugatorProfile, Identity) {
  EXPECT_EQ(p_.device, "corrugator");
  EXPECT_EQ(p_.device_type, 0x01A4u);
}

TEST_F(CorrugatorProfile, EveryVariableMatchesTheSpec) {
  struct Expect {
    std::uint16_t index;
    const char* name;
    DataType type;
    Access access;
    const char* unit;
    double scale;
    const char* eng_unit;
    std::optional<std::int64_t> min, max;
  };
  const std::optional<std::int64_t> none;
  // Tables 14-31 and 39-46: all Mandatory VARs.
  const std::vector<Expect> objects{
      {0x6000, "corrugator_speed_actual_value", DataType::integer16, Access::ro, "0.01 %", 0.01, "%", -10000, 10000},
      {0x6001, "corrugator_speed_real_maximum", DataType::unsigned32, Access::const_, "mm/min", 0.001, "m/min", none, none},
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
  for (const auto& e : objects) {
    const auto* o = p_.object(e.index);
    ASSERT_NE(o, nullptr) << std::hex << e.index;
    EXPECT_EQ(o->name, e.name);
    EXPECT_EQ(o->type, e.type) << e.name;
    EXPECT_EQ(o->access, e.access) << e.name;
    EXPECT_EQ(o->unit, e.unit) << e.name;
    EXPECT_DOUBLE_EQ(o->scale, e.scale) << e.name;
    EXPECT_EQ(o->eng_unit, e.eng_unit) << e.name;
    EXPECT_EQ(o->min, e.min) << e.name;
    EXPECT_EQ(o->max, e.max) << e.name;
    EXPECT_TRUE(o->mandatory) << e.name;
    EXPECT_EQ(p_.object(e.index, 1), nullptr) << e.name << ": VAR, not ARRAY";
  }
  // Unlike the puller 1.0, 6007h has no "not configured" code in 3.1.
  EXPECT_TRUE(p_.object(0x6007)->values.empty());
  // 12 VARs and 3 optional ARRAYs of 10 elements + sub 0.
  EXPECT_EQ(p_.objects.size(), 12u + 3u * 11u);
}

TEST_F(CorrugatorProfile, ArraysOfTenElements) {
  struct Expect {
    std::uint16_t index;
    const char* name;
    DataType type;
    Access access;
    const char* unit;
    double scale;
    const char* eng_unit;
    std::optional<std::int64_t> min, max;
  };
  const std::optional<std::int64_t> none;
  // Tables 32-37: Optional ARRAYs, sub 0 const (highest sub-index 01h..0Ah), subs 01h..0Ah.
  const std::vector<Expect> arrays{
      {0x6009, "height_adjustment", DataType::integer16, Access::rw, "0.1 mm", 0.0001, "m", none, none},
      {0x600A, "pressure_set_value", DataType::unsigned16, Access::rw, "0.01 %", 0.01, "%", 0, 10000},
      {0x600B, "actual_temperature", DataType::integer16, Access::ro, "0.1 °C", 0.1, "°C", -2732, 32767},
  };
  for (const auto& e : arrays) {
    const auto* count = p_.object(e.index, 0);
    ASSERT_NE(count, nullptr) << e.name;
    EXPECT_EQ(count->type, DataType::unsigned8);
    EXPECT_EQ(count->access, Access::const_);
    EXPECT_FALSE(count->mandatory);
    for (std::uint8_t sub = 1; sub <= 10; ++sub) {
      const auto* o = p_.object(e.index, sub);
      ASSERT_NE(o, nullptr) << e.name << " sub " << int{sub};
      EXPECT_EQ(o->name, std::string(e.name) + "_" + std::to_string(sub));
      EXPECT_EQ(o->type, e.type) << o->name;
      EXPECT_EQ(o->access, e.access) << o->name;
      EXPECT_EQ(o->unit, e.unit) << o->name;
      EXPECT_DOUBLE_EQ(o->scale, e.scale) << o->name;
      EXPECT_EQ(o->eng_unit, e.eng_unit) << o->name;
      EXPECT_EQ(o->min, e.min) << o->name;
      EXPECT_EQ(o->max, e.max) << o->name;
      EXPECT_FALSE(o->mandatory) << o->name;
    }
    EXPECT_EQ(p_.object(e.index, 11), nullptr) << e.name;
  }
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
  const auto* t1 = p_.pdo("tpdo1");
  const auto* t2 = p_.pdo("tpdo2");
  const auto* r1 = p_.pdo("rpdo1");
  ASSERT_TRUE(t1 && t2 && r1);
  EXPECT_EQ(p_.pdos.size(), 3u);
  EXPECT_EQ(t1->cob_id(0x12), 0x192u);
  EXPECT_EQ(t2->cob_id(0x12), 0x292u);
  EXPECT_EQ(r1->cob_id(0x12), 0x212u);
  for (const auto& pdo : p_.pdos) {
    EXPECT_EQ(pdo.transmission_type, 1) << pdo.name;
    EXPECT_EQ(pdo.validity, PdoValidity::valid) << pdo.name;
    EXPECT_TRUE(pdo.mandatory) << pdo.name;
  }
  EXPECT_EQ(t1->direction, PdoDirection::tx);
  EXPECT_EQ(t2->direction, PdoDirection::tx);
  EXPECT_EQ(r1->direction, PdoDirection::rx);
  EXPECT_EQ(t1->mapping, entries({0x60300010, 0x60000010, 0x60060010}));
  EXPECT_EQ(t2->mapping, entries({0x60040010, 0x60080020}));
  EXPECT_EQ(r1->mapping, entries({0x60200010, 0x60020010}));
  // Table 1 note: TPDO1 and RPDO1 may carry one manufacturer-specific object.
  ASSERT_TRUE(t1->manufacturer_data);
  EXPECT_EQ(t1->manufacturer_data->name, "manufacturer_status_word");
  EXPECT_EQ(t1->manufacturer_data->bits, 16u);
  ASSERT_TRUE(r1->manufacturer_data);
  EXPECT_EQ(r1->manufacturer_data->name, "manufacturer_control_word");
  EXPECT_EQ(r1->manufacturer_data->bits, 16u);
  EXPECT_FALSE(t2->manufacturer_data);
}

TEST_F(CorrugatorProfile, Tpdo1StatusSpeedAndLoad) {
  // Status 4081h: drive running (0), master-extruder enabled (7), start cut pulse (14);
  // speed 5000 = 1388h (50 %); load -1 = FFFFh (-0.01 %).
  Image img(p_, "tpdo1");
  const std::array<std::uint8_t, 6> frame{0x81, 0x40, 0x88, 0x13, 0xFF, 0xFF};
  ASSERT_TRUE(img.unpack(frame));
  const auto sw = img.raw(0x6030);
  EXPECT_EQ(sw, 0x4081u);
  const auto* bits = p_.bitset("status_word");
  EXPECT_EQ(bits->field("drive_running")->extract(sw), 1u);
  EXPECT_EQ(bits->field("master_extruder_enabled")->extract(sw), 1u);
  EXPECT_EQ(bits->field("start_cut_pulse")->extract(sw), 1u);
  EXPECT_EQ(bits->field("fault")->extract(sw), 0u);
  EXPECT_DOUBLE_EQ(p_.object(0x6000)->to_engineering(img.raw(0x6000)), 50.0);
  EXPECT_DOUBLE_EQ(p_.object(0x6006)->to_engineering(img.raw(0x6006)), -0.01);
  const std::array<std::uint8_t, 8> longer{0x81, 0x40, 0x88, 0x13, 0xFF, 0xFF, 0x01, 0x80};
  EXPECT_EQ(p_.pdo("tpdo1")->manufacturer_value(longer), 0x8001u);
  EXPECT_EQ(p_.pdo("tpdo1")->manufacturer_value(frame), std::nullopt);
}

TEST_F(CorrugatorProfile, Tpdo2EchoAndProductSpeed) {
  // Echo -10000 = D8F0h (-100 %); product speed -123456 = FFFE 1DC0h in 0.1 mm/min = -12.3456 m/min.
  Image img(p_, "tpdo2");
  const std::array<std::uint8_t, 6> frame{0xF0, 0xD8, 0xC0, 0x1D, 0xFE, 0xFF};
  ASSERT_TRUE(img.unpack(frame));
  EXPECT_DOUBLE_EQ(p_.object(0x6004)->to_engineering(img.raw(0x6004)), -100.0);
  EXPECT_DOUBLE_EQ(p_.object(0x6008)->to_engineering(img.raw(0x6008)), -12.3456);
}

TEST_F(CorrugatorProfile, Rpdo1ControlAndSpeedSetValue) {
  // Control 0406h: drive start (1), move in (2), f2 start (10); 75.5 % = 7550 = 1D7Eh.
  Image img(p_, "rpdo1");
  const auto* set = p_.object(0x6002);
  auto raw = set->to_raw(75.5);
  ASSERT_TRUE(raw);
  EXPECT_EQ(*raw, 7550u);
  const auto* cw = p_.bitset("control_word");
  std::uint64_t word = 0;
  for (const char* name : {"drive_start", "move_in", "f2_start"}) word = cw->field(name)->insert(word, 1);
  EXPECT_EQ(word, 0x0406u);
  img.set(0x6020, word);
  img.set(0x6002, *raw);
  EXPECT_EQ(img.pack(), (std::vector<std::uint8_t>{0x06, 0x04, 0x7E, 0x1D}));
  Image monitor(p_, "rpdo1");
  const std::array<std::uint8_t, 4> frame{0x06, 0x04, 0x7E, 0x1D};
  ASSERT_TRUE(monitor.unpack(frame));
  EXPECT_EQ(monitor.raw(0x6020), 0x0406u);
  EXPECT_DOUBLE_EQ(set->to_engineering(monitor.raw(0x6002)), 75.5);
  EXPECT_FALSE(set->to_raw(-100.01));
}

TEST_F(CorrugatorProfile, ControlStatusAndConfigurationBits) {
  expect_bits(p_, "control_word",
              {{"drive_stop", 0}, {"drive_start", 1}, {"move_in", 2}, {"move_out", 3}, {"extruder_running", 6},
               {"f1_stop", 7}, {"f1_start", 8}, {"f2_stop", 9}, {"f2_start", 10}, {"f3_stop", 11}, {"f3_start", 12}});
  expect_bits(p_, "status_word",
              {{"drive_running", 0}, {"drive_ready_to_start", 1}, {"fault", 3}, {"alarm", 4}, {"increase_request", 5},
               {"decrease_request", 6}, {"master_extruder_enabled", 7}, {"f1_running", 8}, {"f1_ready", 9},
               {"f2_running", 10}, {"f2_ready", 11}, {"f3_running", 12}, {"f3_ready", 13}, {"start_cut_pulse", 14}});
  expect_bits(p_, "configuration_word",
              {{"speed_measuring", 0}, {"height_adjustment", 1}, {"pressure_set_values", 2}, {"actual_temperatures", 3},
               {"f1_available", 4}, {"f2_available", 5}, {"f3_available", 6}});
  EXPECT_EQ(p_.bitset("control_word")->index, 0x6020);
  EXPECT_EQ(p_.bitset("status_word")->index, 0x6030);
  EXPECT_EQ(p_.bitset("configuration_word")->index, 0x6010);
}
