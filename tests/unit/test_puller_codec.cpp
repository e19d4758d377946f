// Puller decoding and encoding against frames written by hand from the specification (CiA 420-2
// 1.0, objects 6000h-6030h, PDO mappings 1A00h/1A01h/1600h) and profile-decisions.md (bit layouts,
// the 3.0 status word). The expected values are typed in here, never computed by the code under
// test. The body of the drive tests: drive_codec_test.hpp.
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "support/unit_cia420_bits.hpp"
#include "unit/drive_codec_test.hpp"

namespace msg = linebridge_msgs::msg;

namespace {

lb::test::DriveVectors puller_vectors() {
  return {
      .node_id = 6,
      // 2.1-2.3: COB-IDs 180h/280h/200h + node-ID, transmission type 1.
      .tpdo1_cob_id = 0x186,
      .tpdo2_cob_id = 0x286,
      .rpdo1_cob_id = 0x206,
      // The bits both versions share (profile-decisions.md "Puller").
      .status_bits = lb::test::cia420_status_bits(
          {{0, "motor_running"}, {1, "motor_ready_to_start"}, {2, "clamp_closed"}}),
      .reserved_status_bits = 0,
      .control_bits = lb::test::cia420_control_bits(
          {{0, "motor_stop"}, {1, "motor_start"}, {2, "clamp_close"}, {3, "clamp_open"}}),
      .momentary = lb::test::cia420_momentary(
          {{"motor_stop", 0}, {"motor_start", 1}, {"clamp_close", 2}, {"clamp_open", 3}}),
      .tpdo1 =
          {
              // 6000h INTEGER16 5000 = 1388h (50 %); 6006h INTEGER16 -1234 = FB2Eh (-12.34 %); a
              // 6-byte TPDO1 carries no second status word.
              {{0x03, 0x00, 0x88, 0x13, 0x2E, 0xFB},
               0x0003,
               {"motor_running", "motor_ready_to_start"},
               50.0,
               -12.34,
               {}},
              // Reversed: -10000 = D8F0h (-100 %); load at the INTEGER16 limit 32767 = 7FFFh (327.67 %).
              {{0x00, 0x00, 0xF0, 0xD8, 0xFF, 0x7F}, 0x0000, {}, -100.0, 327.67, {}},
              // 1A00h note: the unused bytes 6..7 carry only a manufacturer-specific second status word.
              {{0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xEF, 0xBE}, 0x0000, {}, 0.0, 0.0, 0xBEEF},
              // The next frame without it: no longer present.
              {{0x00, 0x00, 0x00, 0x00, 0x00, 0x00}, 0x0000, {}, 0.0, 0.0, {}},
          },
      // 6004h INTEGER16 2500 = 09C4h (25 %); 6008h INTEGER32 0.1 mm/min 123456 = 0001E240h =
      // 12.3456 m/min, beyond the printed 0..10000 and still published.
      .tpdo2 = {{{0xC4, 0x09, 0x40, 0xE2, 0x01, 0x00}, 25.0, 12.3456}},
      .rpdo1 =
          {
              // Extruder running = 6020h bit 6 (0040h); 50 % = 5000 = 1388h.
              {{}, true, 50.0, {0x40, 0x00, 0x88, 0x13, 0, 0, 0, 0}},
              // Reverse: -12.5 % = -1250 = FB1Eh; extruder stopped.
              {{}, false, -12.5, {0x00, 0x00, 0x1E, 0xFB, 0, 0, 0, 0}},
              // Motor start (bit 1) held: 0042h; 100 % = 10000 = 2710h.
              {{1}, true, 100.0, {0x42, 0x00, 0x10, 0x27, 0, 0, 0, 0}},
          },
      // 6002h: -10000..10000 (-100..100 %).
      .refused = {100.01, -100.01, std::nan(""), std::numeric_limits<double>::infinity()},
      .accepted = {-100.0},
      // 12.345 % -> 1234.5 raw -> 1235 (half away from zero).
      .rounding = {{12.345, 1235}},
  };
}

struct Puller10 {
  using Binding = linebridge_msgs::bindings::Puller;
  static constexpr const char* profile_id = "cia420-2";
  static constexpr const char* version = "1.0";
  static lb::test::DriveVectors vectors() { return puller_vectors(); }
};
struct Puller30 : Puller10 {
  static constexpr const char* version = "3.0-status";
};

}  // namespace

namespace lb::test {
using PullerVersions = ::testing::Types<Puller10, Puller30>;
INSTANTIATE_TYPED_TEST_SUITE_P(Puller, DriveCodecTest, PullerVersions);
}  // namespace lb::test

namespace {

// What differs between the versions: the 3.0 status word.
template <class Case>
class PullerVersionTest : public lb::test::DriveCodecTest<Case> {};
using PullerVersions = ::testing::Types<Puller10, Puller30>;
TYPED_TEST_SUITE(PullerVersionTest, PullerVersions);

TYPED_TEST(PullerVersionTest, Version10ReverseDirectionIsBit7AndThe30StatusWordMovesIt) {
  const bool v30 = std::string(TypeParam::version) == "3.0-status";
  this->tpdo1(0x0080);  // bit 7: reverse direction in 1.0, reserved in 3.0
  EXPECT_EQ(this->status().status_word().reverse_direction(), !v30);
  this->tpdo1(0x4000);  // bit 14: reserved in 1.0, reverse direction in 3.0
  EXPECT_EQ(this->status().status_word().reverse_direction(), v30);
  EXPECT_EQ(this->status().status_word().raw(), 0x4000);
  // Bit 15: reserved in 1.0; speed set mode in 3.0 (1 = remote, 0 = local).
  this->tpdo1(0x8000);
  EXPECT_EQ(this->status().status_word().speed_set_mode(),
            v30 ? msg::PULLER_SPEED_SET_REMOTE : msg::PULLER_SPEED_SET_NOT_REPORTED);
  this->tpdo1(0x0000);
  EXPECT_EQ(this->status().status_word().speed_set_mode(),
            v30 ? msg::PULLER_SPEED_SET_LOCAL : msg::PULLER_SPEED_SET_NOT_REPORTED);
}

TYPED_TEST(PullerVersionTest, SetEchoDifferenceIsFlaggedOnlyAfterTheSettlingTime) {
  auto& codec = this->codec_;
  const auto tpdo2 = this->pdo("tpdo2");
  codec.apply(*codec.validate(this->setpoint(true, 50.0)));  // 6002h = 5000
  // TPDO2 with echo 0: the device has not taken the value yet. Three samples are settling time.
  const std::array<std::uint8_t, 6> old_echo{0x00, 0x00, 0x00, 0x00, 0x00, 0x00};
  for (int i = 0; i < 3; ++i) {
    ASSERT_TRUE(codec.receive(tpdo2, old_echo));
    EXPECT_FALSE(this->status().set_echo_mismatch()) << "sample " << i;
  }
  ASSERT_TRUE(codec.receive(tpdo2, old_echo));
  EXPECT_TRUE(this->status().set_echo_mismatch());
  EXPECT_DOUBLE_EQ(this->status().speed_set_echo_percent(), 0.0);
  // 4999 = 1387h: within the tolerance of 1 raw unit, clears it.
  const std::array<std::uint8_t, 6> close{0x87, 0x13, 0x00, 0x00, 0x00, 0x00};
  ASSERT_TRUE(codec.receive(tpdo2, close));
  EXPECT_FALSE(this->status().set_echo_mismatch());
  // 4998 = 1386h: two units off, flagged after the settling time again.
  const std::array<std::uint8_t, 6> off{0x86, 0x13, 0x00, 0x00, 0x00, 0x00};
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(codec.receive(tpdo2, off));
  EXPECT_TRUE(this->status().set_echo_mismatch());
  // A new set value restarts the settling time.
  codec.apply(*codec.validate(this->setpoint(true, 49.98)));
  EXPECT_FALSE(this->status().set_echo_mismatch());
  ASSERT_TRUE(codec.receive(tpdo2, off));
  EXPECT_FALSE(this->status().set_echo_mismatch());
}

}  // namespace
