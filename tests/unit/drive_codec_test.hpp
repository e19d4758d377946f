#pragma once
// One test body for every drive-like type's codec (DriveCodec<Binding>); each type's file gives
// its golden vectors, written by hand from its specification and profile-decisions.md, never
// computed by the code under test. The generated word binding is used only to reach a field by
// the name the vectors give it.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "gateways/codecs/drive_codec.hpp"
#include "gateways/commands/command_service.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "support/codec_pdo.hpp"

namespace lb::test {

using Frame = std::vector<std::uint8_t>;
using NamedBit = std::pair<unsigned, std::string_view>;  // bit -> the message field of that name

struct DriveVectors {
  std::uint8_t node_id = 0;
  std::uint32_t tpdo1_cob_id = 0, tpdo2_cob_id = 0, rpdo1_cob_id = 0;
  std::vector<NamedBit> status_bits;       // every named bit a single-bit word must show alone
  std::uint16_t reserved_status_bits = 0;  // bits that show in raw only
  std::vector<NamedBit> control_bits;
  std::vector<std::pair<std::string, unsigned>> momentary;  // commands, in order, and their bits
  struct Tpdo1 {
    Frame frame;
    std::uint16_t status_word;
    std::vector<std::string_view> set_flags;  // status word fields that must be true
    double speed_percent, load_percent;
    std::optional<std::uint16_t> manufacturer;  // nullopt: not present, published as 0
  };
  std::vector<Tpdo1> tpdo1;
  struct Tpdo2 {
    Frame frame;
    double echo_percent, product_m_per_min;
  };
  std::vector<Tpdo2> tpdo2;
  struct Rpdo1 {
    std::vector<unsigned> held;  // momentary control bits held while the set value is applied
    bool extruder_running;
    double speed_percent;
    std::array<std::uint8_t, 8> frame;
  };
  std::vector<Rpdo1> rpdo1;
  std::vector<double> refused;   // set values out of 6002h's range (the first: the reason checked)
  std::vector<double> accepted;  // at the edges
  std::vector<std::pair<double, std::uint64_t>> rounding;  // percent -> raw 6002h
};

// Case: using Binding; static constexpr const char* profile_id, version; static DriveVectors vectors().
template <class Case>
class DriveCodecTest : public ::testing::Test {
 protected:
  using Binding = typename Case::Binding;
  using Status = typename Binding::Status;

  DriveCodecTest()
      : v_(Case::vectors()),
        registry_(profiles::ProfileRegistry::builtin()),
        profile_(*registry_.find(Case::profile_id, Case::version)),
        pdos_(profiles::default_pdos(profile_, v_.node_id)) {}

  std::size_t pdo(const std::string& name) const { return pdo_index(codec_, name); }
  Status status() const {
    Status s;
    codec_.fill(s);
    return s;
  }
  typename Binding::Setpoint setpoint(bool extruder_running, double percent) const {
    typename Binding::Setpoint sp;
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
    const std::array<std::uint8_t, 6> f{static_cast<std::uint8_t>(sw),    static_cast<std::uint8_t>(sw >> 8),
                                        static_cast<std::uint8_t>(speed), static_cast<std::uint8_t>(speed >> 8),
                                        static_cast<std::uint8_t>(load),  static_cast<std::uint8_t>(load >> 8)};
    ASSERT_TRUE(codec_.receive(pdo("tpdo1"), f));
  }
  template <class Word, class Flags>
  static bool field(const Word& w, const Flags& flags, std::string_view name) {
    for (const auto& f : flags) {
      if (f.name == name) return (w.*f.get)();
    }
    ADD_FAILURE() << "no field " << name;
    return false;
  }
  bool status_flag(const Status& s, std::string_view name) const {
    return field(s.status_word(), Binding::status_flags, name);
  }
  bool control_flag(const Status& s, std::string_view name) const {
    return field(s.control_word(), Binding::control_flags, name);
  }

  DriveVectors v_;
  profiles::ProfileRegistry registry_;
  const profiles::Profile& profile_;
  std::vector<profiles::DevicePdo> pdos_;
  gateways::DriveCodec<Binding> codec_{profile_, pdos_};
};

TYPED_TEST_SUITE_P(DriveCodecTest);

TYPED_TEST_P(DriveCodecTest, DefaultPdoCommunicationFromTheSpec) {
  const auto& p = this->codec_.pdos();
  EXPECT_EQ(p[this->pdo("tpdo1")].def->can_id, this->v_.tpdo1_cob_id);
  EXPECT_EQ(p[this->pdo("tpdo2")].def->can_id, this->v_.tpdo2_cob_id);
  EXPECT_EQ(p[this->pdo("rpdo1")].def->can_id, this->v_.rpdo1_cob_id);
  for (const auto& x : p) EXPECT_EQ(x.def->transmission_type, 1);
  // TPDO1: 6030h, 6000h, 6006h (16 each); TPDO2: 6004h (16), 6008h (32); RPDO1: 6020h, 6002h.
  EXPECT_EQ(p[this->pdo("tpdo1")].binding.mapping().byte_length(), 6u);
  EXPECT_EQ(p[this->pdo("tpdo2")].binding.mapping().byte_length(), 6u);
  EXPECT_EQ(p[this->pdo("rpdo1")].binding.mapping().byte_length(), 4u);
}

TYPED_TEST_P(DriveCodecTest, EveryStatusBitHasItsName) {
  const auto& bits = this->v_.status_bits;
  for (const auto& [bit, name] : bits) {
    const auto word = static_cast<std::uint16_t>(1U << bit);
    this->tpdo1(word);
    const auto s = this->status();
    EXPECT_EQ(s.status_word().raw(), word);
    for (const auto& [other, other_name] : bits) {
      EXPECT_EQ(this->status_flag(s, other_name), other == bit) << "status bit " << bit << " set, field " << other_name;
    }
  }
  if (this->v_.reserved_status_bits != 0) {
    this->tpdo1(this->v_.reserved_status_bits);
    const auto s = this->status();
    EXPECT_EQ(s.status_word().raw(), this->v_.reserved_status_bits);
    for (const auto& [bit, name] : bits) EXPECT_FALSE(this->status_flag(s, name)) << name;
  }
}

TYPED_TEST_P(DriveCodecTest, Tpdo1ValuesInEngineeringUnits) {
  for (const auto& t : this->v_.tpdo1) {
    ASSERT_TRUE(this->codec_.receive(this->pdo("tpdo1"), t.frame));
    const auto s = this->status();
    EXPECT_EQ(s.status_word().raw(), t.status_word);
    for (const auto name : t.set_flags) EXPECT_TRUE(this->status_flag(s, name)) << name;
    EXPECT_DOUBLE_EQ(s.speed_actual_percent(), t.speed_percent);
    EXPECT_DOUBLE_EQ(s.load_actual_percent(), t.load_percent);
    EXPECT_EQ(s.manufacturer_status_word_present(), t.manufacturer.has_value())
        << "a frame of " << t.frame.size() << " bytes";
    EXPECT_EQ(s.manufacturer_status_word(), t.manufacturer.value_or(0));
  }
}

TYPED_TEST_P(DriveCodecTest, Tpdo2EchoAndProductSpeed) {
  for (const auto& t : this->v_.tpdo2) {
    ASSERT_TRUE(this->codec_.receive(this->pdo("tpdo2"), t.frame));
    EXPECT_DOUBLE_EQ(this->status().speed_set_echo_percent(), t.echo_percent);
    EXPECT_DOUBLE_EQ(this->status().product_speed_m_per_min(), t.product_m_per_min);
  }
}

TYPED_TEST_P(DriveCodecTest, ShortPdoIsRefusedAndNothingChanges) {
  const auto& good = this->v_.tpdo2.at(0);
  ASSERT_TRUE(this->codec_.receive(this->pdo("tpdo2"), good.frame));
  const std::array<std::uint8_t, 5> short_frame{0xFF, 0xFF, 0xFF, 0xFF, 0xFF};
  EXPECT_FALSE(this->codec_.receive(this->pdo("tpdo2"), short_frame));
  EXPECT_DOUBLE_EQ(this->status().speed_set_echo_percent(), good.echo_percent);
}

TYPED_TEST_P(DriveCodecTest, SetValuesAndHeldCommandsBecomeTheRpdo1Frame) {
  for (const auto& r : this->v_.rpdo1) {
    std::uint8_t held_mask = 0;
    for (const auto bit : r.held) {
      this->codec_.set_control_bit(bit, true);
      held_mask |= static_cast<std::uint8_t>(1U << bit);
    }
    auto raw = this->codec_.validate(this->setpoint(r.extruder_running, r.speed_percent));
    ASSERT_TRUE(raw) << raw.error().message;
    this->codec_.apply(*raw);
    EXPECT_EQ(this->rpdo1(), r.frame) << r.speed_percent << " %";
    const auto s = this->status();
    EXPECT_EQ(s.control_word().extruder_running(), r.extruder_running);
    EXPECT_DOUBLE_EQ(s.speed_set_percent(), r.speed_percent);
    for (const auto bit : r.held) {
      for (const auto& [b, name] : this->v_.control_bits) {
        if (b == bit) {
          EXPECT_TRUE(this->control_flag(s, name)) << name;
        }
      }
    }
    // Released, the set value stays.
    for (const auto bit : r.held) this->codec_.set_control_bit(bit, false);
    EXPECT_EQ(this->rpdo1()[0], static_cast<std::uint8_t>(r.frame[0] & ~held_mask));
  }
  for (const auto& [percent, raw] : this->v_.rounding) {
    EXPECT_EQ(this->codec_.validate(this->setpoint(true, percent))->speed_set, raw) << percent << " %";
  }
}

TYPED_TEST_P(DriveCodecTest, OutOfRangeSetValuesAreRefusedWithTheReason) {
  ASSERT_FALSE(this->v_.refused.empty());
  auto r = this->codec_.validate(this->setpoint(true, this->v_.refused.front()));
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("speed_set_percent"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("out of range"), std::string::npos) << r.error().message;
  for (const auto percent : this->v_.refused)
    EXPECT_FALSE(this->codec_.validate(this->setpoint(true, percent))) << percent;
  for (const auto percent : this->v_.accepted)
    EXPECT_TRUE(this->codec_.validate(this->setpoint(true, percent))) << percent;
  EXPECT_EQ(this->rpdo1(), (std::array<std::uint8_t, 8>{}));
}

TYPED_TEST_P(DriveCodecTest, EveryControlBitHasItsNameAndTheMomentaryOnesAreCommands) {
  const auto& bits = this->v_.control_bits;
  for (const auto& [bit, name] : bits) {
    this->codec_.set_control_bit(bit, true);
    const auto s = this->status();
    EXPECT_EQ(s.control_word().raw(), 1U << bit);
    for (const auto& [other, other_name] : bits)
      EXPECT_EQ(this->control_flag(s, other_name), other == bit) << bit << "/" << other;
    this->codec_.set_control_bit(bit, false);
  }
  const auto commands = gateways::resolve_commands(this->codec_.bitset("control_word"),
                                                   gateways::momentary_commands<typename TestFixture::Binding>());
  const auto& expected = this->v_.momentary;
  ASSERT_EQ(commands.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(commands[i].name, expected[i].first);
    EXPECT_EQ(commands[i].bit, expected[i].second);
  }
}

REGISTER_TYPED_TEST_SUITE_P(DriveCodecTest, DefaultPdoCommunicationFromTheSpec, EveryStatusBitHasItsName,
                            Tpdo1ValuesInEngineeringUnits, Tpdo2EchoAndProductSpeed, ShortPdoIsRefusedAndNothingChanges,
                            SetValuesAndHeldCommandsBecomeTheRpdo1Frame, OutOfRangeSetValuesAreRefusedWithTheReason,
                            EveryControlBitHasItsNameAndTheMomentaryOnesAreCommands);

}  // namespace lb::test
