// Corrugator decoding and encoding against frames written by hand from CiA 420-3 3.1 (objects
// 6000h-6030h, Tables 3-13) and profile-decisions.md (the status and control word layouts). The
// expected values are typed in here, never computed by the code under test. The body of the drive
// tests: drive_codec_test.hpp.
#include <array>
#include <cmath>

#include "support/unit_cia420_bits.hpp"
#include "unit/drive_codec_test.hpp"

namespace {

struct Corrugator31 {
  using Binding = linebridge_msgs::bindings::Corrugator;
  static constexpr const char* profile_id = "cia420-3";
  static constexpr const char* version = "3.1";
  static lb::test::DriveVectors vectors() {
    return {
        .node_id = 7,
        // Tables 3/7/11: 4000 0180h/0280h/0200h + node-ID (bit 30: no RTR), transmission type 1.
        .tpdo1_cob_id = 0x187,
        .tpdo2_cob_id = 0x287,
        .rpdo1_cob_id = 0x207,
        .status_bits = lb::test::cia420_status_bits({{0, "drive_running"},
                                                     {1, "drive_ready_to_start"},
                                                     {7, "master_extruder_enabled"},
                                                     {14, "start_cut_pulse"}}),
        // Bits 2 and 15 are reserved: raw only.
        .reserved_status_bits = 0x8004,
        .control_bits = lb::test::cia420_control_bits(
            {{0, "drive_stop"}, {1, "drive_start"}, {2, "move_in"}, {3, "move_out"}}),
        .momentary = lb::test::cia420_momentary(
            {{"drive_stop", 0}, {"drive_start", 1}, {"move_in", 2}, {"move_out", 3}}),
        // TPDO1: status 0083h (running, ready, master-extruder enabled); 6000h 7550 = 1D7Eh
        // (75.5 %); 6006h 4321 = 10E1h (43.21 % of the maximum load); manufacturer word 1234h.
        .tpdo1 = {{{0x83, 0x00, 0x7E, 0x1D, 0xE1, 0x10, 0x34, 0x12},
                   0x0083,
                   {"drive_running", "drive_ready_to_start", "master_extruder_enabled"},
                   75.5,
                   43.21,
                   0x1234}},
        // TPDO2: 6004h 7550 = 1D7Eh; 6008h 0.1 mm/min, -150000 = FFFD B610h (-15 m/min, reversed).
        .tpdo2 = {{{0x7E, 0x1D, 0x10, 0xB6, 0xFD, 0xFF}, 75.5, -15.0}},
        .rpdo1 =
            {
                // Extruder running (bit 6) with drive start held (bit 1): 0042h; 75.5 % = 7550 = 1D7Eh.
                {{1}, true, 75.5, {0x42, 0x00, 0x7E, 0x1D, 0, 0, 0, 0}},
                // -0.01 % = -1 = FFFFh (reverse is allowed: 6002h -10000..+10000).
                {{}, false, -0.01, {0x00, 0x00, 0xFF, 0xFF, 0, 0, 0, 0}},
            },
        .refused = {150.0, -100.01, std::nan("")},
        .accepted = {100.004},  // 10000.4 -> 10000 raw
        .rounding = {},
    };
  }
};

}  // namespace

namespace lb::test {
INSTANTIATE_TYPED_TEST_SUITE_P(Corrugator, DriveCodecTest, ::testing::Types<Corrugator31>);
}  // namespace lb::test

namespace {

using CorrugatorTest = lb::test::DriveCodecTest<Corrugator31>;

TEST_F(CorrugatorTest, MonitorRoleComparesTheEchoWithTheRpdo1SeenOnTheBus) {
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

}  // namespace
