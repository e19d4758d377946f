// Saw profile CiA 420-4 draft 1.0 (spec file 004, sections 2 and 3.1) and profile-decisions.md,
// side by side with 3.1 (spec file 002). Frames are written by hand (little-endian) and decoded by
// the production PDO codec; expected values are typed in.
#include <gtest/gtest.h>

#include <cstdint>
#include <utility>
#include <vector>

#include "support/profile_spec.hpp"

using namespace lb::test::spec;

namespace {

// Spec file 004 figures 3.1.12/3.1.13 (bit order) and profile-decisions.md (f pairs).
const Bits kControl10{{"saw_program_on", 0}, {"wall_thickening", 1},  {"change_of_length", 2}, {"manual_cut", 3},
                      {"tip_pulse", 4},      {"stop_immediately", 5}, {"f1_stop", 6},          {"f1_start", 7},
                      {"f2_stop", 8},        {"f2_start", 9},         {"f3_stop", 10},         {"f3_start", 11}};
const Bits kStatus10{{"saw_ready", 0},  {"saw_cutting", 1}, {"sample_request", 2}, {"manual_cut_by_saw", 3},
                     {"fault", 4},      {"alarm", 5},       {"f1_running", 6},     {"f1_ready", 7},
                     {"f2_running", 8}, {"f2_ready", 9},    {"f3_running", 10},    {"f3_ready", 11}};

class Saw10Profile : public ::testing::Test {
 protected:
  lb::profiles::ProfileRegistry registry_ = lb::profiles::ProfileRegistry::builtin();
  const Profile& p_ = *registry_.find("cia420-4", "1.0");
  const Profile& p31_ = *registry_.find("cia420-4", "3.1");
};

// Status 0003h (saw ready, saw cutting); counter 1234 5678h pulses, up to FFFF FFFFh: unsigned.
// Saw counter -25 = FFFF FFE7h in 0.1 mm = -0.0025 m (wrong direction); speed 12000 = 2EE0h mm/min.
// Control 0005h (program on, change of length); 33.33 % = 3333 = 0D05h; 1.5 m = 15000 = 3A98h.
const auto kFrames = frames_of(
    "cia420-4", "1.0",
    {
        {"Tpdo1StatusAndCounter",
         "tpdo1",
         {0x03, 0x00, 0x78, 0x56, 0x34, 0x12},
         {{0x6030, 0, 0x0003}, {0x6000, 0, 0x12345678}},
         {{"status_word", "saw_ready", 1}, {"status_word", "saw_cutting", 1}, {"status_word", "sample_request", 0}}},
        {"Tpdo1CounterAtItsTop",
         "tpdo1",
         {0x00, 0x00, 0xFF, 0xFF, 0xFF, 0xFF},
         {{0x6030, 0, 0x0000}, {0x6000, 0, 0xFFFFFFFF, 4294967295.0}}},
        {"Tpdo2SawCounterAndProductSpeed",
         "tpdo2",
         {0xE7, 0xFF, 0xFF, 0xFF, 0xE0, 0x2E, 0x00, 0x00},
         {{0x6001, 0, 0xFFFFFFE7, -0.0025}, {0x6007, 0, 0x2EE0, 12.0}}},
        {"Rpdo1ControlSyncSpeedAndLength",
         "rpdo1",
         {0x05, 0x00, 0x05, 0x0D, 0x98, 0x3A, 0x00, 0x00},
         {{0x6020, 0, 0x0005}, {0x6005, 0, 0x0D05, 33.33}, {0x6002, 0, 0x3A98, 1.5}}},
    });

}  // namespace

INSTANTIATE_TEST_SUITE_P(Saw10, ProfileFrame, ::testing::ValuesIn(kFrames), frame_name);

TEST_F(Saw10Profile, Identity) {
  EXPECT_EQ(p_.device, "saw");
  EXPECT_EQ(p_.device_type, 0x01A4u);
}

TEST_F(Saw10Profile, EveryObjectMatchesTheSpec) {
  // Sections 3.1.1-3.1.13: every object is a Mandatory VAR.
  const std::vector<Variable> objects{
      {0x6000, "counter_value", DataType::unsigned32, Access::ro, "pulse", 1.0, "pulse", none, none},
      {0x6001, "actual_saw_counter", DataType::integer32, Access::ro, "0.1 mm", 0.0001, "m", none, none},
      {0x6002, "product_length_set_value", DataType::integer32, Access::wo, "0.1 mm", 0.0001, "m", none, none},
      {0x6003, "scaling_factor", DataType::unsigned32, Access::rw, "pulse/m", 1.0, "pulse/m", none, none},
      {0x6004, "saw_minimum_product_length", DataType::integer32, Access::ro, "0.1 mm", 0.0001, "m", none, none},
      {0x6005, "saw_sync_speed_set_value", DataType::unsigned16, Access::rw, "0.01 %", 0.01, "%", 0, 10000},
      {0x6006, "saw_sync_speed_set_maximum", DataType::integer32, Access::ro, "mm/min", 0.001, "m/min", none, none},
      {0x6007, "product_speed", DataType::integer32, Access::ro, "mm/min", 0.001, "m/min", none, none},
      {0x6009, "height_adjustment", DataType::integer16, Access::wo, "0.1 mm", 0.0001, "m", none, none},
      {0x600A, "saw_cut_depth", DataType::integer16, Access::wo, "mm", 0.001, "m", none, none},
      {0x6010, "configuration_word", DataType::unsigned32, Access::ro, "", 1.0, "", none, none},
      {0x6020, "control_word", DataType::unsigned16, Access::rw, "", 1.0, "", none, none},
      {0x6030, "status_word", DataType::unsigned16, Access::ro, "", 1.0, "", none, none},
  };
  EXPECT_EQ(p_.objects.size(), objects.size());
  expect_variables(p_, objects);
  // 3.1.4: FFFF FFFFh = scaling factor not configured.
  EXPECT_FALSE(p_.object(0x6003)->values.exhaustive);
  EXPECT_EQ(p_.object(0x6003)->values.name(0xFFFFFFFFu), "not_configured");
}

TEST_F(Saw10Profile, WhatDiffersFrom31) {
  struct Side {
    DataType type;
    Access access;
    bool mandatory;
  };
  struct Diff {
    std::uint16_t index;
    std::uint8_t sub31;  // 6009h is an ARRAY in 3.1: compare its first element
    Side v10;
    Side v31;
  };
  // profile-decisions.md, "Differences 1.0 -> 3.1".
  const std::vector<Diff> diffs{
      {0x6002, 0, {DataType::integer32, Access::wo, true}, {DataType::unsigned32, Access::rw, true}},
      {0x6004, 0, {DataType::integer32, Access::ro, true}, {DataType::unsigned32, Access::ro, true}},
      {0x6006, 0, {DataType::integer32, Access::ro, true}, {DataType::unsigned32, Access::rw, true}},
      {0x6009, 1, {DataType::integer16, Access::wo, true}, {DataType::integer16, Access::rw, false}},
      {0x600A, 0, {DataType::integer16, Access::wo, true}, {DataType::unsigned16, Access::rw, false}},
  };
  for (const auto& d : diffs) {
    const auto* a = p_.object(d.index);
    const auto* b = p31_.object(d.index, d.sub31);
    ASSERT_TRUE(a && b) << std::hex << d.index;
    EXPECT_EQ(a->type, d.v10.type) << a->name;
    EXPECT_EQ(a->access, d.v10.access) << a->name;
    EXPECT_EQ(a->mandatory, d.v10.mandatory) << a->name;
    EXPECT_EQ(b->type, d.v31.type) << b->name;
    EXPECT_EQ(b->access, d.v31.access) << b->name;
    EXPECT_EQ(b->mandatory, d.v31.mandatory) << b->name;
  }
  // 6009h: one value in 1.0, ARRAY of up to 10 in 3.1.
  EXPECT_EQ(p_.object(0x6009, 1), nullptr);
  EXPECT_NE(p31_.object(0x6009, 10), nullptr);
  // "Not configured" exists only in 1.0.
  EXPECT_EQ(p_.object(0x6003)->values.name(0xFFFFFFFFu), "not_configured");
  EXPECT_TRUE(p31_.object(0x6003)->values.empty());
  // Objects only in 3.1.
  for (std::uint16_t index : {0x6008, 0x600B, 0x6031, 0x6032}) {
    EXPECT_EQ(p_.object(index), nullptr) << std::hex << index;
    EXPECT_NE(p31_.object(index), nullptr) << std::hex << index;
  }
  // Objects alike in both.
  for (std::uint16_t index : {0x6000, 0x6001, 0x6003, 0x6005, 0x6007, 0x6010, 0x6020, 0x6030}) {
    const auto* a = p_.object(index);
    const auto* b = p31_.object(index);
    ASSERT_TRUE(a && b) << std::hex << index;
    EXPECT_EQ(a->name, b->name);
    EXPECT_EQ(a->type, b->type) << a->name;
    EXPECT_EQ(a->access, b->access) << a->name;
    EXPECT_DOUBLE_EQ(a->scale, b->scale) << a->name;
  }
  // The same default PDOs in both versions.
  for (const char* name : {"tpdo1", "tpdo2", "rpdo1"}) {
    ASSERT_TRUE(p_.pdo(name) && p31_.pdo(name)) << name;
    EXPECT_EQ(p_.pdo(name)->mapping, p31_.pdo(name)->mapping) << name;
    EXPECT_EQ(p_.pdo(name)->cob_id_base, p31_.pdo(name)->cob_id_base) << name;
  }
}

TEST_F(Saw10Profile, BitsSideBySideWith31) {
  expect_bits(p_, "control_word", kControl10);
  expect_bits(p_, "status_word", kStatus10);
  expect_bits(p_, "configuration_word", {{"speed_measuring", 0}});
  // 3.1 keeps every 1.0 bit where it was...
  for (const char* set : {"control_word", "status_word", "configuration_word"}) {
    for (const auto& f : p_.bitset(set)->bits) {
      EXPECT_EQ(p31_.bitset(set)->bit(f.name), f.bit) << set << "." << f.name;
    }
  }
  // ...and adds these.
  const std::vector<std::pair<const char*, Bits>> only31{
      {"control_word", {{"count_mode", 12}}},
      {"status_word",
       {{"saw_program_enabled", 12}, {"cut_from_limit_switch", 13}, {"start_saw_program_requested", 14}}},
      {"configuration_word",
       {{"height_adjustment", 1},
        {"cut_depth", 2},
        {"f1_available", 3},
        {"f2_available", 4},
        {"f3_available", 5},
        {"early_warning", 6},
        {"corrugator_cut_management", 7},
        {"groove_count_mode", 8}}},
  };
  for (const auto& [set, bits] : only31) {
    for (const auto& [name, bit] : bits) {
      EXPECT_EQ(p_.bitset(set)->field(name), nullptr) << set << "." << name;
      EXPECT_EQ(p31_.bitset(set)->bit(name), bit) << set << "." << name;
    }
  }
}

TEST_F(Saw10Profile, DefaultPdos) {
  // 2.1-2.3: TPDO1 180h, TPDO2 280h, RPDO1 200h (+ node-ID), transmission type 1; the 1.0 text has
  // no note of a manufacturer-specific object.
  expect_pdos(p_, 3,
              {
                  {"tpdo1", PdoDirection::tx, 0x183, 1, PdoValidity::valid, true, entries({0x60300010, 0x60000020})},
                  {"tpdo2", PdoDirection::tx, 0x283, 1, PdoValidity::valid, true, entries({0x60010020, 0x60070020})},
                  {"rpdo1", PdoDirection::rx, 0x203, 1, PdoValidity::valid, true,
                   entries({0x60200010, 0x60050010, 0x60020020})},
              });
}

TEST_F(Saw10Profile, ProductLengthIsSignedIn10AndUnsignedIn31) {
  // 1.0 INTEGER32: -1 m = -10000 = FFFF D8F0h is a value; 3.1 UNSIGNED32 refuses it.
  const auto v10 = p_.object(0x6002)->to_raw(-1.0);
  ASSERT_TRUE(v10);
  Image img(p_, "rpdo1");
  img.set(0x6002, *v10);
  const auto bytes = img.pack();
  EXPECT_EQ(std::vector<std::uint8_t>(bytes.begin() + 4, bytes.end()),
            (std::vector<std::uint8_t>{0xF0, 0xD8, 0xFF, 0xFF}));
  EXPECT_FALSE(p31_.object(0x6002)->to_raw(-1.0));
  // Upper ends: INTEGER32 stops at 214748.3647 m, UNSIGNED32 at 429496.7295 m.
  EXPECT_TRUE(p_.object(0x6002)->to_raw(214748.3647));
  EXPECT_FALSE(p_.object(0x6002)->to_raw(214748.3648));
  EXPECT_TRUE(p31_.object(0x6002)->to_raw(214748.3648));
}
