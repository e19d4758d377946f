// Saw 3.1 decoding and encoding against frames written by hand from the specification
// (EUROMAP 27-4 / CiA 420-4 tables 1-13, objects 6000h-6030h) and profile-decisions.md (bit
// layouts). The expected values are typed in here, never computed by the code under test.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "gateways/codecs/saw_codec.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "support/codec_pdo.hpp"
#include "support/unit_codec_fixture.hpp"

namespace msg = linebridge_msgs::msg;

namespace {

class SawCodecTest : public lb::test::CodecOnProfile<lb::gateways::SawCodec> {
 protected:
  SawCodecTest() : CodecOnProfile("cia420-4", "3.1", 3) {}

  msg::SawStatus status() const {
    msg::SawStatus s;
    codec_.fill(s);
    return s;
  }
  msg::SawSetpoint setpoint(bool on, double percent, double length_m) const {
    msg::SawSetpoint sp;
    sp.saw_program_on(on);
    sp.sync_speed_percent(percent);
    sp.product_length_m(length_m);
    sp.count_mode(msg::SMOOTH_PIPE);
    return sp;
  }
  std::array<std::uint8_t, 8> rpdo1() const {
    std::array<std::uint8_t, 8> out{};
    EXPECT_EQ(codec_.pack(pdo("rpdo1"), out), 8);
    return out;
  }
};

}  // namespace

TEST_F(SawCodecTest, DefaultPdoCommunicationFromTheSpec) {
  // Table 3/7/11: COB-IDs 180h/280h/200h + node-ID, transmission type 1 (synchronous).
  const auto& p = codec_.pdos();
  EXPECT_EQ(p[pdo("tpdo1")].def->can_id, 0x183u);
  EXPECT_EQ(p[pdo("tpdo2")].def->can_id, 0x283u);
  EXPECT_EQ(p[pdo("rpdo1")].def->can_id, 0x203u);
  EXPECT_EQ(p[pdo("tpdo1")].def->cob_id_entry(), 0x183u);  // valid, 11-bit
  for (const auto& x : p) EXPECT_EQ(x.def->transmission_type, 1);
  // Tables 5/9/13: the default mappings.
  EXPECT_EQ(p[pdo("tpdo1")].binding.mapping().byte_length(), 6u);
  EXPECT_EQ(p[pdo("tpdo2")].binding.mapping().byte_length(), 8u);
  EXPECT_EQ(p[pdo("rpdo1")].binding.mapping().byte_length(), 8u);
}

TEST_F(SawCodecTest, EveryStatusBitHasItsName) {
  using Getter = std::function<bool(const msg::SawStatusWord&)>;
  const std::vector<std::pair<unsigned, Getter>> bits{
      {0, [](auto& w) { return w.saw_ready(); }},
      {1, [](auto& w) { return w.saw_cutting(); }},
      {2, [](auto& w) { return w.sample_request(); }},
      {3, [](auto& w) { return w.manual_cut_by_saw(); }},
      {4, [](auto& w) { return w.fault(); }},
      {5, [](auto& w) { return w.alarm(); }},
      {6, [](auto& w) { return w.f1_running(); }},
      {7, [](auto& w) { return w.f1_ready(); }},
      {8, [](auto& w) { return w.f2_running(); }},
      {9, [](auto& w) { return w.f2_ready(); }},
      {10, [](auto& w) { return w.f3_running(); }},
      {11, [](auto& w) { return w.f3_ready(); }},
      {12, [](auto& w) { return w.saw_program_enabled(); }},
      {13, [](auto& w) { return w.cut_from_limit_switch(); }},
      {14, [](auto& w) { return w.start_saw_program_requested(); }},
  };
  for (const auto& [bit, get] : bits) {
    // TPDO1: status word (16, LE) then counter value (32, LE).
    const std::uint16_t word = static_cast<std::uint16_t>(1U << bit);
    const std::array<std::uint8_t, 6> frame{
        static_cast<std::uint8_t>(word), static_cast<std::uint8_t>(word >> 8), 0, 0, 0, 0};
    ASSERT_TRUE(codec_.receive(pdo("tpdo1"), frame));
    const auto s = status();
    EXPECT_EQ(s.status_word().raw(), word);
    for (const auto& [other, get_other] : bits) {
      EXPECT_EQ(get_other(s.status_word()), other == bit) << "status bit " << bit << " set, field of bit " << other;
    }
  }
  // Bit 15 is reserved: it shows in raw only.
  const std::array<std::uint8_t, 6> reserved{0x00, 0x80, 0, 0, 0, 0};
  ASSERT_TRUE(codec_.receive(pdo("tpdo1"), reserved));
  EXPECT_EQ(status().status_word().raw(), 0x8000);
  EXPECT_FALSE(codec_.cutting());
}

TEST_F(SawCodecTest, CounterValueIsUnsigned32Pulses) {
  // 6000h UNSIGNED32, counts up to FFFF FFFFh.
  const std::array<std::uint8_t, 6> frame{0x02, 0x00, 0xFF, 0xFF, 0xFF, 0xFF};
  ASSERT_TRUE(codec_.receive(pdo("tpdo1"), frame));
  EXPECT_EQ(status().counter_value(), 0xFFFFFFFFu);
  EXPECT_TRUE(codec_.cutting());
}

TEST_F(SawCodecTest, SawCounterInTenthMillimetresAndSpeedInMillimetresPerMinute) {
  // TPDO2: 6001h INTEGER32 0.1 mm = 12345 (1.2345 m); 6007h INTEGER32 mm/min = 25000 (25 m/min).
  const std::array<std::uint8_t, 8> frame{0x39, 0x30, 0x00, 0x00, 0xA8, 0x61, 0x00, 0x00};
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), frame));
  EXPECT_DOUBLE_EQ(status().actual_saw_counter_m(), 1.2345);
  EXPECT_DOUBLE_EQ(status().product_speed_m_per_min(), 25.0);
}

TEST_F(SawCodecTest, NegativeValuesMeanWrongDirection) {
  // -10 (0.1 mm) = FFFF FFF6h; -1500 mm/min = FFFF FA24h.
  const std::array<std::uint8_t, 8> frame{0xF6, 0xFF, 0xFF, 0xFF, 0x24, 0xFA, 0xFF, 0xFF};
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), frame));
  EXPECT_DOUBLE_EQ(status().actual_saw_counter_m(), -0.001);
  EXPECT_DOUBLE_EQ(status().product_speed_m_per_min(), -1.5);
}

TEST_F(SawCodecTest, ShortPdoIsRefusedAndNothingChanges) {
  const std::array<std::uint8_t, 8> good{0x39, 0x30, 0x00, 0x00, 0xA8, 0x61, 0x00, 0x00};
  ASSERT_TRUE(codec_.receive(pdo("tpdo2"), good));
  const std::array<std::uint8_t, 7> short_frame{0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00};
  EXPECT_FALSE(codec_.receive(pdo("tpdo2"), short_frame));
  EXPECT_DOUBLE_EQ(status().actual_saw_counter_m(), 1.2345);
}

TEST_F(SawCodecTest, SetValueBecomesTheRpdo1Frame) {
  // Program on (bit 0), change of length toggled (bit 2) because the length changed from 0:
  // control word 0005h; 50 % = 5000 = 1388h (0.01 %); 1.2345 m = 12345 = 3039h (0.1 mm).
  auto raw = codec_.validate(setpoint(true, 50.0, 1.2345));
  ASSERT_TRUE(raw) << raw.error().message;
  codec_.apply(*raw);
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{0x05, 0x00, 0x88, 0x13, 0x39, 0x30, 0x00, 0x00}));

  // Same length again: no toggle. Program off clears bit 0 only.
  codec_.apply(*codec_.validate(setpoint(false, 50.0, 1.2345)));
  EXPECT_EQ(rpdo1()[0], 0x04);
  // A new length toggles bit 2 back to 0: 2 m = 20000 = 4E20h.
  codec_.apply(*codec_.validate(setpoint(true, 100.0, 2.0)));
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{0x01, 0x00, 0x10, 0x27, 0x20, 0x4E, 0x00, 0x00}));
  const auto s = status();
  EXPECT_TRUE(s.control_word().saw_program_on());
  EXPECT_FALSE(s.control_word().change_of_length());
  EXPECT_DOUBLE_EQ(s.product_length_set_m(), 2.0);
  EXPECT_DOUBLE_EQ(s.sync_speed_set_percent(), 100.0);
}

TEST_F(SawCodecTest, CorrugatedModeSetsControlBit12) {
  auto sp = setpoint(true, 10.0, 1.0);
  sp.count_mode(msg::CORRUGATED_PIPE);
  codec_.apply(*codec_.validate(sp));
  EXPECT_EQ(rpdo1()[1], 0x10);  // bit 12 = byte 1 bit 4
  EXPECT_EQ(status().control_word().count_mode(), msg::CORRUGATED_PIPE);
}

// 6020h bit 1 "wall-thickening active" (spec file 004's order): a level, set with the set values.
TEST_F(SawCodecTest, WallThickeningIsControlBit1) {
  auto sp = setpoint(true, 10.0, 0.0);
  sp.wall_thickening(true);
  codec_.apply(*codec_.validate(sp));
  EXPECT_EQ(rpdo1()[0], 0x03);  // bit 0 program on, bit 1 wall-thickening
  EXPECT_TRUE(status().control_word().wall_thickening());
  sp.wall_thickening(false);
  codec_.apply(*codec_.validate(sp));
  EXPECT_EQ(rpdo1()[0], 0x01);
  EXPECT_FALSE(status().control_word().wall_thickening());
}

// Saw 3.1 TPDO1 sub 3 is manufacturer-specific: a device maps 2110h there, the line names it
// (device objects:); it arrives after 6030h and 6000h and is published by name.
TEST_F(SawCodecTest, AnObjectBeyondTheTypedStatusIsPublishedByName) {
  lb::profiles::Profile extended = profile_;
  lb::profiles::ObjectDef second;
  second.index = 0x2110;
  second.name = "second_status_word";
  second.type = lb::canopen::DataType::unsigned16;
  extended.objects.push_back(second);
  auto pdos = lb::profiles::default_pdos(extended, 3);
  for (auto& p : pdos) {
    if (p.name == "tpdo1") p.mapping.push_back(lb::canopen::PdoEntry::from_u32(0x21100010));
  }
  lb::gateways::SawCodec codec(extended, pdos);
  const std::array<std::uint8_t, 8> frame{0x01, 0x00, 0x10, 0x27, 0x00, 0x00, 0x34, 0x12};  // 2110h = 1234h
  ASSERT_TRUE(codec.receive(lb::test::pdo_index(codec, "tpdo1"), frame));
  msg::SawStatus s;
  codec.fill(s);
  EXPECT_EQ(s.counter_value(), 10000u);
  ASSERT_EQ(s.other_values().size(), 1u);
  const auto& v = s.other_values()[0];
  EXPECT_EQ(v.name(), "second_status_word");
  EXPECT_EQ(v.index(), 0x2110);
  EXPECT_EQ(v.pdo(), "tpdo1");
  EXPECT_EQ(v.raw(), 0x1234);
  EXPECT_DOUBLE_EQ(v.value(), 4660.0);
  // The line's own profile objects are no "other" values: the default codec has none.
  msg::SawStatus plain;
  codec_.fill(plain);
  EXPECT_TRUE(plain.other_values().empty());
}

TEST_F(SawCodecTest, RoundsToTheNearestRawUnit) {
  // 12.125 % -> 1212.5 raw -> 1213 (half away from zero); 0.00004 m -> 0.4 raw -> 0.
  auto raw = codec_.validate(setpoint(true, 12.125, 0.00004));
  ASSERT_TRUE(raw);
  EXPECT_EQ(raw->sync_speed, 1213u);
  EXPECT_EQ(raw->product_length, 0u);
  raw = codec_.validate(setpoint(true, 12.124, 1.23456));
  ASSERT_TRUE(raw);
  EXPECT_EQ(raw->sync_speed, 1212u);
  EXPECT_EQ(raw->product_length, 12346u);
}

TEST_F(SawCodecTest, OutOfRangeSetValuesAreRefusedWithTheReason) {
  // 6005h: 0..10000 (0..100 %).
  auto r = codec_.validate(setpoint(true, 100.01, 1.0));
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("sync_speed_percent"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("out of range"), std::string::npos) << r.error().message;
  EXPECT_FALSE(codec_.validate(setpoint(true, -0.01, 1.0)));
  // 6002h UNSIGNED32 in 0.1 mm: negative lengths and lengths beyond 429496.7295 m are refused.
  r = codec_.validate(setpoint(true, 50.0, -1.0));
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("product_length_m"), std::string::npos) << r.error().message;
  EXPECT_FALSE(codec_.validate(setpoint(true, 50.0, 429497.0)));
  EXPECT_TRUE(codec_.validate(setpoint(true, 50.0, 429496.7295)));
  EXPECT_FALSE(codec_.validate(setpoint(true, std::nan(""), 1.0)));
  EXPECT_FALSE(codec_.validate(setpoint(true, 50.0, std::numeric_limits<double>::infinity())));
  // Nothing refused reached the image.
  EXPECT_EQ(rpdo1(), (std::array<std::uint8_t, 8>{}));
}

TEST_F(SawCodecTest, SawProfileObjectsMatchTheSpec) {
  struct Expect {
    std::uint16_t index;
    lb::canopen::DataType type;
    lb::profiles::Access access;
  };
  using lb::canopen::DataType;
  using lb::profiles::Access;
  const std::vector<Expect> objects{
      {0x6000, DataType::unsigned32, Access::ro}, {0x6001, DataType::integer32, Access::ro},
      {0x6002, DataType::unsigned32, Access::rw}, {0x6003, DataType::unsigned32, Access::rw},
      {0x6004, DataType::unsigned32, Access::ro}, {0x6005, DataType::unsigned16, Access::rw},
      {0x6006, DataType::unsigned32, Access::rw}, {0x6007, DataType::integer32, Access::ro},
      {0x6008, DataType::unsigned32, Access::ro}, {0x600A, DataType::unsigned16, Access::rw},
      {0x600B, DataType::unsigned32, Access::rw}, {0x6010, DataType::unsigned32, Access::ro},
      {0x6020, DataType::unsigned16, Access::rw}, {0x6030, DataType::unsigned16, Access::ro},
      {0x6031, DataType::unsigned32, Access::ro}, {0x6032, DataType::unsigned32, Access::rw},
  };
  for (const auto& e : objects) {
    const auto* o = profile_.object(e.index);
    ASSERT_NE(o, nullptr) << std::hex << e.index;
    EXPECT_EQ(o->type, e.type) << std::hex << e.index;
    EXPECT_EQ(o->access, e.access) << std::hex << e.index;
  }
  // 6009h: ARRAY of INTEGER16, subs 1..10 (0Ah).
  for (std::uint8_t sub = 1; sub <= 10; ++sub) ASSERT_NE(profile_.object(0x6009, sub), nullptr);
  EXPECT_EQ(profile_.object(0x6009, 11), nullptr);
  // Every control and configuration bit named in profile-decisions.md.
  const auto* cw = profile_.bitset("control_word");
  const std::vector<std::pair<const char*, unsigned>> control{
      {"saw_program_on", 0},   {"wall_thickening", 1}, {"change_of_length", 2}, {"manual_cut", 3}, {"tip_pulse", 4},
      {"stop_immediately", 5}, {"f1_stop", 6},         {"f1_start", 7},         {"f2_stop", 8},    {"f2_start", 9},
      {"f3_stop", 10},         {"f3_start", 11},       {"count_mode", 12}};
  for (const auto& [name, bit] : control) EXPECT_EQ(cw->bit(name), bit) << name;
  const auto* cfg = profile_.bitset("configuration_word");
  const std::vector<std::pair<const char*, unsigned>> config{{"speed_measuring", 0},  {"height_adjustment", 1},
                                                             {"cut_depth", 2},        {"f1_available", 3},
                                                             {"f2_available", 4},     {"f3_available", 5},
                                                             {"early_warning", 6},    {"corrugator_cut_management", 7},
                                                             {"groove_count_mode", 8}};
  for (const auto& [name, bit] : config) EXPECT_EQ(cfg->bit(name), bit) << name;
}
