// Feeder (CiA 414-2 1.1.0) decoding and validation against words and frames written by hand from
// the specification (spec file 000: 4.1 EMCY FF10h, 4.2-4.6 PDOs, 5.2.2 6001h, 5.2.13 600Ch, 5.2.15
// 600Eh, 5.2.16 600Fh, 5.2.17 6010h) and profile-decisions.md (6001h, 6004h layouts, FF10h bytes).
// Expected values are typed in here, never computed by the code under test.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "gateways/codecs/feeder_codec.hpp"
#include "profiles/line_config.hpp"
#include "profiles/profile_registry.hpp"
#include "support/codec_pdo.hpp"
#include "support/unit_codec_fixture.hpp"

namespace msg = linebridge_msgs::msg;
using lb::gateways::FeederCodec;

namespace {

class FeederCodecTest : public lb::test::CodecOnProfile<FeederCodec> {
 protected:
  FeederCodecTest() : CodecOnProfile("cia414-2", "1.1", 10) {}

  void receive(const std::string& name, std::vector<std::uint8_t> bytes) {
    ASSERT_TRUE(codec_.receive(pdo(name), bytes)) << name;
  }
  msg::LoomSide loom() const {
    msg::LoomSide l;
    codec_.fill_loom(l, true);
    return l;
  }
  std::vector<std::uint8_t> pack(const std::string& name) const {
    std::array<std::uint8_t, 8> out{};
    const auto len = codec_.pack(pdo(name), out);
    return {out.begin(), out.begin() + len};
  }
  static std::vector<std::uint8_t> colours(const msg::PickInsertion& p) {
    return {p.colours().begin(), p.colours().end()};
  }
};

TEST_F(FeederCodecTest, Tpdo1UnwindingTimeBitFields) {
  // 6010h = 0x030C01C8: feeder 03h (bits 31-24), winding 0Ch = 12 (23-16), 01C8h = 456 x 0.1 ms.
  receive("tpdo1", {0xC8, 0x01, 0x0C, 0x03});
  const auto u = codec_.last_unwinding();
  EXPECT_EQ(u.raw(), 0x030C01C8u);
  EXPECT_EQ(u.feeder_selected(), 3);
  EXPECT_EQ(u.winding_number(), 12);
  EXPECT_DOUBLE_EQ(u.coil_unwinding_time_ms(), 45.6);
  EXPECT_TRUE(u.in_range());

  // Feeder FEh, winding 50, 1000 x 0.1 ms: the top of every printed range.
  const auto top = codec_.unwinding(0xFE3203E8);
  EXPECT_EQ(top.feeder_selected(), 254);
  EXPECT_EQ(top.winding_number(), 50);
  EXPECT_DOUBLE_EQ(top.coil_unwinding_time_ms(), 100.0);
  EXPECT_TRUE(top.in_range());
  // Winding 51 (allowed 1..50) and 1001 x 0.1 ms (allowed 0..1000): published, flagged.
  EXPECT_FALSE(codec_.unwinding(0x013303E8).in_range());
  EXPECT_FALSE(codec_.unwinding(0x010103E9).in_range());
  EXPECT_FALSE(codec_.unwinding(0x00010000).in_range()) << "feeder 00h is not a feeder";
}

TEST_F(FeederCodecTest, Rpdo1PickInsertionDecodedPerTable) {
  // 00h empty, 07h single colour 7, 10h single colour 16, A3h double 10 and 3, 55h triple 5, 7, 9.
  receive("rpdo1", {0x00, 0x07, 0x10, 0xA3, 0x55});
  auto l = loom();
  EXPECT_TRUE(l.seen());
  ASSERT_EQ(l.pick_insertion().size(), 5u);
  const auto& p = l.pick_insertion();
  EXPECT_EQ(p[0].kind(), "empty_pick");
  EXPECT_TRUE(p[0].valid());
  EXPECT_TRUE(colours(p[0]).empty());
  EXPECT_EQ(p[1].kind(), "single_pick");
  EXPECT_EQ(colours(p[1]), (std::vector<std::uint8_t>{7}));
  EXPECT_EQ(p[2].kind(), "single_pick");
  EXPECT_EQ(colours(p[2]), (std::vector<std::uint8_t>{16}));
  EXPECT_EQ(p[3].kind(), "double_pick");
  EXPECT_EQ(colours(p[3]), (std::vector<std::uint8_t>{10, 3}));
  EXPECT_EQ(p[4].kind(), "triple_pick");
  EXPECT_EQ(colours(p[4]), (std::vector<std::uint8_t>{5, 7, 9}));
  EXPECT_EQ(colours(codec_.pick(0xCC)), (std::vector<std::uint8_t>{12, 14, 16}));
  EXPECT_EQ(colours(codec_.pick(0x11)), (std::vector<std::uint8_t>{1, 3, 5})) << "11h is a triple pick, not a double";

  // DDh reserved; 12h breaks "HighNibble = 0 or HighNibble >= LowNibble"; 20h is in no row.
  receive("rpdo1", {0xDD, 0x12, 0x20, 0xFF, 0xFE});
  l = loom();
  for (std::size_t i = 0; i < 4; ++i) {
    EXPECT_FALSE(l.pick_insertion()[i].valid()) << i;
    EXPECT_EQ(l.pick_insertion()[i].kind(), "") << i;
    EXPECT_TRUE(colours(l.pick_insertion()[i]).empty()) << i;
  }
  EXPECT_EQ(l.pick_insertion()[0].raw(), 0xDD);
  EXPECT_EQ(l.pick_insertion()[1].raw(), 0x12);
  EXPECT_EQ(l.pick_insertion()[4].kind(), "double_pick");
  EXPECT_EQ(colours(l.pick_insertion()[4]), (std::vector<std::uint8_t>{15, 14}));
}

TEST_F(FeederCodecTest, Rpdo2AndRpdo4LoomSide) {
  EXPECT_FALSE(loom().seen());
  // 600Ah 01h start advice; 6004h = 00BE 03E8h: loom width 190 cm, maximum speed 1000 1/min.
  receive("rpdo2", {0x01, 0xE8, 0x03, 0xBE, 0x00});
  receive("rpdo4", {0x02});
  auto l = loom();
  EXPECT_EQ(l.loom_status().name(), "start_advice");
  EXPECT_EQ(l.weft_filling_raw(), 0x00BE03E8u);
  EXPECT_EQ(l.maximum_speed_per_min(), 1000);
  EXPECT_DOUBLE_EQ(l.loom_width_m(), 1.90);
  EXPECT_EQ(l.trigger_signal().name(), "pick_release_trigger");
  // 05h..FEh are reserved loom states and triggers: raw, invalid, no name.
  receive("rpdo2", {0x05, 0, 0, 0, 0});
  receive("rpdo4", {0x07});
  l = loom();
  EXPECT_FALSE(l.loom_status().valid());
  EXPECT_EQ(l.loom_status().raw(), 5);
  EXPECT_EQ(l.loom_status().name(), "");
  EXPECT_FALSE(l.trigger_signal().valid());
  EXPECT_EQ(l.trigger_signal().raw(), 7);
}

TEST_F(FeederCodecTest, FunctionsTwoBitFields) {
  // BR 11 on, WD 11 Z, AT 10 off | YB 11 active, IKD 10 not active, YQ 00 n/a, RD 01 undefined, TKS 11.
  // 1111 1000 0000 0000 0011 1000 0111 0000b = F800 3870h.
  const auto f = codec_.functions(0xF8003870);
  EXPECT_EQ(f.raw(), 0xF8003870u);
  EXPECT_EQ(f.brush_release().state(), "on");
  EXPECT_TRUE(f.brush_release().available());
  EXPECT_TRUE(f.brush_release().on());
  EXPECT_EQ(f.winding_direction().state(), "z");
  EXPECT_EQ(f.angle_trigger_monitoring().state(), "off");
  EXPECT_TRUE(f.angle_trigger_monitoring().available());
  EXPECT_FALSE(f.angle_trigger_monitoring().on());
  EXPECT_EQ(f.yarn_break_sensor().state(), "active");
  EXPECT_EQ(f.input_knot_detection_sensor().state(), "not_active");
  EXPECT_EQ(f.yarn_quality_sensor().state(), "not_available");
  EXPECT_FALSE(f.yarn_quality_sensor().available());
  EXPECT_FALSE(f.rotation_direction_sensor().valid()) << "01b is undefined";
  EXPECT_EQ(f.rotation_direction_sensor().raw(), 1);
  EXPECT_EQ(f.rotation_direction_sensor().state(), "");
  EXPECT_FALSE(f.rotation_direction_sensor().available());
  EXPECT_EQ(f.tks_sensor().state(), "active");
  EXPECT_EQ(codec_.functions(0x20000000).winding_direction().state(), "s");
  EXPECT_FALSE(codec_.functions(0).winding_direction().valid()) << "WD has no 'not available' code";
}

TEST_F(FeederCodecTest, Ff10BitmapNamesFeedersInError) {
  // EMCY 10 FF 01 | 05 00 00 80 | 00: bits 0, 2 and 31 = feeders 1, 3 and 32.
  const std::uint32_t bitmap = FeederCodec::ff10_bitmap({0x05, 0x00, 0x00, 0x80, 0x00});
  EXPECT_EQ(bitmap, 0x80000005u);
  EXPECT_TRUE(FeederCodec::in_bitmap(bitmap, 1));
  EXPECT_FALSE(FeederCodec::in_bitmap(bitmap, 2));
  EXPECT_TRUE(FeederCodec::in_bitmap(bitmap, 3));
  EXPECT_TRUE(FeederCodec::in_bitmap(bitmap, 32));
  EXPECT_FALSE(FeederCodec::in_bitmap(bitmap, 33)) << "FF10h carries feeders 1..32 only";
  EXPECT_FALSE(FeederCodec::in_bitmap(bitmap, 0));
  EXPECT_EQ(FeederCodec::ff10_bitmap({0, 0, 0, 0, 0xFF}), 0u) << "EMCY byte 7 is not part of the bitmap";
}

TEST_F(FeederCodecTest, CodesFromTablesOrInvalid) {
  EXPECT_EQ(codec_.feeder_status(7).name(), "error_mode");
  EXPECT_FALSE(codec_.feeder_status(8).valid());
  EXPECT_EQ(codec_.error_condition(0x04).name(), "yarn_broken");
  EXPECT_FALSE(codec_.error_condition(0x10).valid());
  EXPECT_EQ(codec_.control_box_error(0x0C).name(), "angle_trigger_signal_missing");
  EXPECT_FALSE(codec_.control_box_error(0x02).valid()) << "02h is reserved for the control box";
}

TEST_F(FeederCodecTest, CommandsAndTestsCheckedBeforeCan) {
  auto reset = codec_.command(2, "reset", 0, 4u);
  ASSERT_TRUE(reset) << reset.error().message;
  EXPECT_EQ(reset->object->index, 0x600E);
  EXPECT_EQ(reset->object->sub, 2);
  EXPECT_EQ(reset->raw, 0x04u);
  const auto fly = codec_.command(2, "fly", 0, 4u).error().message;
  EXPECT_NE(fly.find("unknown feeder command"), std::string::npos);
  EXPECT_NE(fly.find("(non_operation_mode, operation_mode, start,"), std::string::npos)
      << "the reason lists the commands: " << fly;
  EXPECT_NE(codec_.command(5, "reset", 0, 4u).error().message.find("reports 4"), std::string::npos);
  EXPECT_FALSE(codec_.command(0, "reset", 0, std::nullopt));
  EXPECT_FALSE(codec_.command(255, "reset", 0, std::nullopt));
  EXPECT_TRUE(codec_.command(254, "led_on", 0, std::nullopt)) << "count unknown: the whole array";
  auto manufacturer = codec_.command(1, "manufacturer_specific", 0x09, 4u);
  ASSERT_TRUE(manufacturer);
  EXPECT_EQ(manufacturer->raw, 0x09u);
  EXPECT_FALSE(codec_.command(1, "manufacturer_specific", 0x60, 4u)) << "60h..FFh reserved";

  // 600Fh: test code in the high byte, parameter in the low byte.
  auto motor = codec_.test(1, "motor_test", 50, 4u);
  ASSERT_TRUE(motor) << motor.error().message;
  EXPECT_EQ(motor->raw, 0x0132u);
  EXPECT_EQ(codec_.test(1, "motor_test", 0, 4u)->raw, 0x0100u) << "0 stops the motor test";
  EXPECT_FALSE(codec_.test(1, "motor_test", 4, 4u));
  EXPECT_FALSE(codec_.test(1, "pin_test", 21, 4u));
  EXPECT_EQ(codec_.test(3, "strobo_function", 1, 4u)->raw, 0x0301u);
  EXPECT_FALSE(codec_.test(3, "strobo_function", 2, 4u));
  EXPECT_EQ(codec_.test(3, "no_test", 99, 4u)->raw, 0x0000u);
}

TEST_F(FeederCodecTest, ConfigurationWritesChecked) {
  // Sim default F: WD 10 S, AT 10 off, YB 11 active, IKD 10, RD 10; BR, YQ, TKS not available.
  const std::uint64_t current = 0x28003880;
  auto merged = codec_.merge_functions(current, {{"yarn_break_sensor", "not_active"}, {"winding_direction", "z"}});
  ASSERT_TRUE(merged) << merged.error().message;
  EXPECT_EQ(*merged, 0x38002880u);
  EXPECT_NE(codec_.merge_functions(current, {{"brush_release", "on"}}).error().message.find("not available"),
            std::string::npos);
  EXPECT_FALSE(codec_.merge_functions(current, {{"tks_sensor", "banana"}}));
  EXPECT_FALSE(codec_.merge_functions(current, {{"angle_trigger_monitoring", "not_available"}}));
  EXPECT_FALSE(codec_.merge_functions(current, {{"warp_drive", "on"}}));

  EXPECT_EQ(codec_.weft_insertion_type("rapier")->raw, 2u);
  EXPECT_FALSE(codec_.weft_insertion_type("jet"));
  EXPECT_EQ(codec_.number_assignment(3, 17, 4u)->object->index, 0x6011);
  EXPECT_EQ(codec_.color_assignment(3, 5, 4u)->object->sub, 3);

  // 6005h sub 2: bit 4 angle trigger via CANopen; supported 0111h.
  auto sources = codec_.trigger_sources({"angle_trigger_via_canopen", "brush_release_via_canopen"}, 0x0111);
  ASSERT_TRUE(sources) << sources.error().message;
  EXPECT_EQ(sources->raw, 0x0011u);
  EXPECT_NE(codec_.trigger_sources({"angle_trigger_via_parallel_line"}, 0x0111).error().message.find("not supported"),
            std::string::npos);

  // Access: 6009h is read-only.
  EXPECT_NE(FeederCodec::checked(*profile_.object("feeder_status_1"), 0).error().message.find("not writable"),
            std::string::npos);
}

TEST_F(FeederCodecTest, LoomSetpointPackedIntoRpdos) {
  msg::LoomSetpoint sp;
  sp.loom_status("start_advice");
  sp.maximum_speed_per_min(1000);
  sp.loom_width_m(1.90);
  sp.pick_insertion({0x00, 0x07, 0x10, 0xA3, 0x55});
  sp.trigger_signal("angle_trigger");
  auto raw = codec_.validate(sp);
  ASSERT_TRUE(raw) << raw.error().message;
  codec_.apply(*raw);
  EXPECT_EQ(pack("rpdo2"), (std::vector<std::uint8_t>{0x01, 0xE8, 0x03, 0xBE, 0x00}));
  EXPECT_EQ(pack("rpdo1"), (std::vector<std::uint8_t>{0x00, 0x07, 0x10, 0xA3, 0x55}));
  EXPECT_EQ(pack("rpdo4"), (std::vector<std::uint8_t>{0x01}));
  EXPECT_TRUE(loom().seen());

  auto bad_pick = sp;
  bad_pick.pick_insertion({0x00, 0x07, 0xDD, 0xA3, 0x55});
  EXPECT_NE(codec_.validate(bad_pick).error().message.find("pick_insertion[2]"), std::string::npos);
  auto four = sp;
  four.pick_insertion({1, 2, 3, 4});
  EXPECT_FALSE(codec_.validate(four));
  auto bad_status = sp;
  bad_status.loom_status("run");
  EXPECT_NE(codec_.validate(bad_status).error().message.find("loom_status"), std::string::npos);
  auto wide = sp;
  wide.loom_width_m(700.0);  // 70000 cm does not fit 16 bits
  EXPECT_NE(codec_.validate(wide).error().message.find("loom_width_m"), std::string::npos);
  EXPECT_FALSE(codec_.validate(msg::LoomSetpoint{})) << "nothing to send";
}

// CiA 414-2 5.2.14: 600Dh "8 x 8 digital output lines", RPDO3 (optional) maps sub 1..8, one byte
// each, in order. Groups not given keep their value.
TEST_F(FeederCodecTest, DigitalOutputsPackedIntoRpdo3) {
  msg::LoomSetpoint sp;
  sp.digital_outputs({0x81, 0x02});
  auto raw = codec_.validate(sp);
  ASSERT_TRUE(raw) << raw.error().message;
  codec_.apply(*raw);
  EXPECT_EQ(pack("rpdo3"), (std::vector<std::uint8_t>{0x81, 0x02, 0, 0, 0, 0, 0, 0}));
  sp.digital_outputs({0x00, 0x00, 0xFF});
  codec_.apply(*codec_.validate(sp));
  EXPECT_EQ(pack("rpdo3"), (std::vector<std::uint8_t>{0x00, 0x00, 0xFF, 0, 0, 0, 0, 0}));
  msg::LoomSide l;
  codec_.fill_loom(l, true);
  EXPECT_EQ(l.digital_outputs(), (std::vector<std::uint8_t>{0x00, 0x00, 0xFF, 0, 0, 0, 0, 0}));
  codec_.fill_loom(l, false);
  EXPECT_TRUE(l.digital_outputs().empty()) << "no outputs where the box has no RPDO3";
  sp.digital_outputs({1, 2, 3, 4, 5, 6, 7, 8, 9});
  EXPECT_FALSE(codec_.validate(sp)) << "600Dh has eight groups";
}

}  // namespace
