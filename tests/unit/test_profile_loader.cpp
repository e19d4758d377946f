// The profile format's keys beyond objects/flags/PDOs: multi-bit fields, value tables (enumerations
// and special values), bit sets of ARRAY elements and record subs, PDO validity, category and
// manufacturer-specific tails; and the file:line:column errors of every new key.
#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>

#include "profiles/profile_registry.hpp"

using lb::profiles::parse_profile;
using lb::profiles::PdoValidity;
using lb::profiles::Profile;

namespace {

// Five lines, so that the first object is on line 7 of every document below.
constexpr const char* kHeader = R"(profile: test
version: "1"
device: test
device_type: 0x01A4
objects:
)";

Profile load(const std::string& body) {
  auto p = parse_profile(kHeader + body, "t.yaml");
  if (!p) ADD_FAILURE() << p.error().message;
  return p ? *p : Profile{};
}

std::string error_of(const std::string& body) {
  auto p = parse_profile(kHeader + body, "t.yaml");
  if (p) {
    ADD_FAILURE() << "loaded, but should have been refused:\n" << body;
    return {};
  }
  return p.error().message;
}

#define EXPECT_ERROR(body, text) EXPECT_EQ(error_of(body), text)

// A 16-bit status word at 6030h and the head of a bitset on it: the fields under test follow, from
// line 11 of t.yaml.
const std::string kBitsetHead =
    "  - {index: 0x6030, name: status_word, type: UNSIGNED16, access: ro}\nbitsets:\n  s:\n    object: 0x6030\n"
    "    bits:\n";

}  // namespace

TEST(ProfileLoader, OneBitFieldsAsBeforeAndMultiBitFields) {
  const auto p = load(R"(  - {index: 0x6010, name: unwinding, type: UNSIGNED32, access: ro}
bitsets:
  fields:
    object: 0x6010
    bits:
      flag: 3
      time: {bit: 0, width: 3}
      selected: {bit: 24, width: 8}
      top: {bit: 15}
)");
  const auto* set = p.bitset("fields");
  ASSERT_NE(set, nullptr);
  EXPECT_EQ(set->bit("flag"), 3u);
  EXPECT_EQ(set->field("flag")->width, 1u);
  EXPECT_EQ(set->bit("top"), 15u);  // a map with only `bit` is a flag too
  // Multi-bit fields are found by field(), never by bit(): a flag reader cannot mistake them.
  EXPECT_EQ(set->bit("selected"), std::nullopt);
  const auto* selected = set->field("selected");
  ASSERT_NE(selected, nullptr);
  EXPECT_EQ(selected->bit, 24u);
  EXPECT_EQ(selected->width, 8u);
  EXPECT_EQ(selected->mask(), 0xFF000000u);
  EXPECT_EQ(selected->extract(0x12345678u), 0x12u);
  EXPECT_EQ(selected->insert(0x12345678u, 0xAB), 0xAB345678u);
  EXPECT_EQ(selected->insert(0, 0x1FF), 0xFF000000u);  // only the field's bits are written
  EXPECT_EQ(set->field("time")->extract(0x0000000Fu), 7u);
  EXPECT_EQ(set->field("nothing"), nullptr);
}

TEST(ProfileLoader, FieldUnitsScaleAndRange) {
  const auto p = load(R"(  - {index: 0x6010, name: unwinding, type: UNSIGNED32, access: ro}
bitsets:
  fields:
    object: 0x6010
    bits:
      time: {bit: 0, width: 16, unit: 0.1 ms, scale: 0.1, eng_unit: ms, min: 0, max: 1000}
      count: {bit: 16, width: 8, min: 1}
)");
  const auto* time = p.bitset("fields")->field("time");
  EXPECT_EQ(time->unit, "0.1 ms");
  EXPECT_EQ(time->eng_unit, "ms");
  EXPECT_DOUBLE_EQ(time->to_engineering(1234), 123.4);
  EXPECT_TRUE(time->in_range(1000));
  EXPECT_FALSE(time->in_range(1001));
  const auto* count = p.bitset("fields")->field("count");
  EXPECT_EQ(count->eng_unit, "");  // defaults to the (empty) raw unit, as for objects
  EXPECT_FALSE(count->in_range(0));
  EXPECT_TRUE(count->in_range(255));
}

TEST(ProfileLoader, EnumerationsNameCodesAndLeaveTheRestInvalid) {
  const auto p = load(R"(  - {index: 0x600E, name: command, type: UNSIGNED8, access: wo,
     values: {0x09..0x5F: manufacturer_specific, 0: off, 1: on, 0b10: start, 3..4: spare}}
)");
  const auto& v = p.object(0x600E)->values;
  EXPECT_TRUE(v.exhaustive);
  EXPECT_EQ(v.name(0), "off");
  EXPECT_EQ(v.name(2), "start");  // 0b binary
  EXPECT_EQ(v.name(4), "spare");
  EXPECT_EQ(v.name(0x09), "manufacturer_specific");
  EXPECT_EQ(v.name(0x5F), "manufacturer_specific");
  EXPECT_EQ(v.name(0x60), std::nullopt);
  EXPECT_FALSE(v.valid(0x60));
  EXPECT_FALSE(v.valid(5));
  EXPECT_TRUE(v.valid(3));
  // Only a name of exactly one code can be sent.
  EXPECT_EQ(v.code("start"), 2u);
  EXPECT_EQ(v.code("spare"), std::nullopt);
  EXPECT_EQ(v.code("manufacturer_specific"), std::nullopt);
  EXPECT_EQ(v.code("nothing"), std::nullopt);
  // Sorted by code whatever the file's order.
  ASSERT_EQ(v.ranges.size(), 5u);
  EXPECT_EQ(v.ranges.front().name, "off");
  EXPECT_EQ(v.ranges.back().name, "manufacturer_specific");
}

TEST(ProfileLoader, SpecialValuesOfANumber) {
  const auto p = load(
      R"(  - {index: 0x6007, name: scaling_factor, type: UNSIGNED32, access: rw, unit: pulse/m, special_values: {0xFFFFFFFF: not_configured}}
  - {index: 0x6008, name: plain, type: UNSIGNED32, access: rw}
)");
  const auto& v = p.object(0x6007)->values;
  EXPECT_FALSE(v.exhaustive);
  EXPECT_EQ(v.name(0xFFFFFFFFu), "not_configured");
  EXPECT_EQ(v.name(10000), std::nullopt);
  EXPECT_TRUE(v.valid(10000));  // just a number
  EXPECT_TRUE(p.object(0x6008)->values.empty());
  EXPECT_TRUE(p.object(0x6008)->values.valid(123));
}

TEST(ProfileLoader, DuplicateNamesMayShareCodes) {
  const auto p = load(
      R"(  - {index: 0x600C, name: pick, type: UNSIGNED8, access: wo, values: {0x01..0x0F: single, 0x10: single}}
)");
  EXPECT_EQ(p.object(0x600C)->values.name(0x10), "single");
  EXPECT_EQ(p.object(0x600C)->values.code("single"), std::nullopt);
}

TEST(ProfileLoader, ArraysCarryValuesAndTheirElementsFollowTheArrayPattern) {
  const auto p = load(R"(  - {index: 0x6009, name: status, type: UNSIGNED8, access: ro, array: 254, values: {0: ok}}
  - {index: 0x600B, name: temperature, type: INTEGER16, access: ro, array: 3, mandatory: false}
)");
  ASSERT_NE(p.object(0x6009, 254), nullptr);
  EXPECT_EQ(p.object(0x6009, 254)->name, "status_254");
  EXPECT_EQ(p.object(0x6009, 254)->values.name(0), "ok");
  EXPECT_FALSE(p.object(0x6009, 0)->writable());
  EXPECT_TRUE(p.object(0x6009, 0)->mandatory);
  EXPECT_TRUE(p.object(0x6009, 1)->mandatory);
  EXPECT_FALSE(p.object(0x6009, 2)->mandatory);
  EXPECT_FALSE(p.object(0x6009, 254)->mandatory);
  EXPECT_FALSE(p.object(0x600B, 0)->mandatory);
  EXPECT_FALSE(p.object(0x600B, 1)->mandatory);
}

TEST(ProfileLoader, BitSetsOfArrayElementsAndOfOneSub) {
  const auto p = load(R"(  - {index: 0x6001, name: functions, type: UNSIGNED32, access: rw, array: 254}
  - {index: 0x6005, sub: 0, name: source_count, type: UNSIGNED8, access: ro}
  - {index: 0x6005, sub: 1, name: supported, type: UNSIGNED16, access: ro}
  - {index: 0x6005, sub: 2, name: selected, type: UNSIGNED16, access: rw}
bitsets:
  functions:
    object: 0x6001
    bits:
      brush_release: {bit: 30, width: 2, values: {0b00: not_available, 0b10: off, 0b11: on}}
  selected:
    object: 0x6005
    sub: 2
    bits: {canopen: 0}
  one_feeder:
    object: 0x6001
    sub: 7
    bits: {top: 31}
)");
  const auto* f = p.bitset("functions");
  EXPECT_TRUE(f->every_element);
  EXPECT_TRUE(f->applies_to(0x6001, 1));
  EXPECT_TRUE(f->applies_to(0x6001, 254));
  EXPECT_FALSE(f->applies_to(0x6001, 0));
  EXPECT_FALSE(f->applies_to(0x6002, 1));
  const auto* br = f->field("brush_release");
  EXPECT_EQ(br->values.name(br->extract(0xC0000000u)), "on");
  EXPECT_EQ(br->values.name(br->extract(0x40000000u)), std::nullopt);  // 01b: undefined
  const auto* s = p.bitset("selected");
  EXPECT_FALSE(s->every_element);
  EXPECT_TRUE(s->applies_to(0x6005, 2));
  EXPECT_FALSE(s->applies_to(0x6005, 1));
  const auto* one = p.bitset("one_feeder");
  EXPECT_FALSE(one->every_element);
  EXPECT_TRUE(one->applies_to(0x6001, 7));
  EXPECT_FALSE(one->applies_to(0x6001, 8));
}

TEST(ProfileLoader, PdoValidityCategoryAndManufacturerData) {
  const auto p = load(R"(  - {index: 0x6000, name: a, type: UNSIGNED8, access: ro}
  - {index: 0x6001, name: b, type: UNSIGNED8, access: rw}
pdos:
  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 255, valid: either, mapping: [0x60000008, 0x00010001],
     manufacturer_data: {name: extra, bits: 12}}
  - {name: tpdo2, direction: tx, cob_id: 0x280, transmission_type: 1, valid: false, mapping: [0x60000008]}
  - {name: rpdo1, direction: rx, cob_id: 0x200, transmission_type: 1, mandatory: false, mapping: [0x60010008]}
  - {name: rpdo2, direction: rx, cob_id: 0x300, transmission_type: 1, valid: true, mapping: [0x60010008]}
)");
  const auto* t1 = p.pdo("tpdo1");
  EXPECT_EQ(t1->validity, PdoValidity::either);
  EXPECT_TRUE(t1->mandatory);
  EXPECT_EQ(p.pdo("tpdo2")->validity, PdoValidity::not_valid);
  EXPECT_EQ(p.pdo("rpdo1")->validity, PdoValidity::valid);
  EXPECT_FALSE(p.pdo("rpdo1")->mandatory);
  EXPECT_EQ(p.pdo("rpdo2")->validity, PdoValidity::valid);
  EXPECT_FALSE(p.pdo("rpdo1")->manufacturer_data.has_value());
  // 8 + 1 mapped bits, then 12 bits of manufacturer data starting at bit 9: LSB first.
  ASSERT_TRUE(t1->manufacturer_data.has_value());
  EXPECT_EQ(t1->manufacturer_data->name, "extra");
  EXPECT_EQ(t1->mapped_bits(), 9u);
  // Byte 1 = 1010 1011b: bit 8 is the dummy (1), bits 9..15 = 1010101b; byte 2 low 5 bits = 10011b.
  const std::array<std::uint8_t, 3> frame{0xFF, 0xAB, 0x13};
  EXPECT_EQ(t1->manufacturer_value(frame), 0b10011'1010101u);
  const std::array<std::uint8_t, 2> short_frame{0xFF, 0xAB};  // 16 < 9 + 12 bits: not carried
  EXPECT_EQ(t1->manufacturer_value(short_frame), std::nullopt);
  EXPECT_EQ(p.pdo("tpdo2")->manufacturer_value(frame), std::nullopt);
}

// Errors: file, line and column of the offending token, and what is wrong.
TEST(ProfileLoaderErrors, FieldWidthAndPosition) {
  EXPECT_ERROR(kBitsetHead + "      a: {bit: 0, width: 0}\n", "t.yaml:11:26: width 0 is outside 1..64");
  EXPECT_ERROR(kBitsetHead + "      a: {bit: 12, width: 5}\n",
               "t.yaml:11:16: bits 16..12 does not exist in a 16-bit word");
  EXPECT_ERROR(kBitsetHead + "      a: 16\n", "t.yaml:11:10: bit 16 does not exist in a 16-bit word");
  EXPECT_ERROR(kBitsetHead + "      a: {width: 2}\n", "t.yaml:11:10: field a: missing required key 'bit'");
  EXPECT_ERROR(kBitsetHead + "      a: {bit: 1, widht: 2}\n",
               "t.yaml:11:19: unknown key 'widht' in field a (allowed: bit, width, unit, scale, eng_unit, min, max, "
               "values, special_values)");
  EXPECT_ERROR(kBitsetHead + "      a: {bit: 1, scale: 0}\n", "t.yaml:11:26: scale must not be 0");
  EXPECT_ERROR(kBitsetHead + "      a: [1, 2]\n", "t.yaml:11:10: 'a' has a value of the wrong type: '<list>'");
}

TEST(ProfileLoaderErrors, OverlappingFields) {
  EXPECT_ERROR(kBitsetHead + "      a: 3\n      b: 3\n", "t.yaml:12:10: bit 3 is already a");
  EXPECT_ERROR(kBitsetHead + "      a: 8\n      b: {bit: 7, width: 2}\n", "t.yaml:12:16: bits 8..7 overlap a (bit 8)");
  EXPECT_ERROR(kBitsetHead + "      a: {bit: 4, width: 4}\n      b: 6\n", "t.yaml:12:10: bit 6 overlaps a (bits 7..4)");
  // yaml-cpp keeps duplicate keys; the loader refuses the second one (as every duplicate key).
  EXPECT_ERROR(kBitsetHead + "      a: 1\n      a: 2\n",
               "t.yaml:12:7: key 'a' is given twice in this mapping (first at line 11, column 7)");
}

TEST(ProfileLoaderErrors, ValueTables) {
  const std::string head = "  - {index: 0x600A, name: loom_status, type: UNSIGNED8, access: wo, values: ";
  EXPECT_ERROR(head + "{x1: stop}}\n",
               "t.yaml:6:78: value code 'x1' must be a number (12, 0x0C, 0b1100) or a range first..last");
  EXPECT_ERROR(head + "{0x100: stop}}\n", "t.yaml:6:78: value code '0x100' does not fit in 8 bits");
  EXPECT_ERROR(head + "{5..3: stop}}\n", "t.yaml:6:78: value range '5..3' runs backwards");
  EXPECT_ERROR(head + "{0..5: stop, 3: run}}\n", "t.yaml:6:90: value code '3' overlaps stop");
  EXPECT_ERROR(head + "{0: Stop}}\n",
               "t.yaml:6:81: value name 'Stop' must be snake_case (a-z, 0-9, _; starting with a letter)");
  EXPECT_ERROR(head + "[stop]}\n", "t.yaml:6:77: values must be a mapping (key: value)");
  EXPECT_ERROR(head + "{0: stop}, special_values: {1: x}}\n",
               "t.yaml:6:104: give either values (an enumeration) or special_values (a number), not both");
  EXPECT_ERROR("  - {index: 0x1008, name: device_name, type: VISIBLE_STRING, access: ro, values: {0: x}}\n",
               "t.yaml:6:82: named codes need an integer data type, not VISIBLE_STRING");
  // A field's codes must fit the field, not the word.
  EXPECT_ERROR(
      "  - {index: 0x6001, name: functions, type: UNSIGNED32, access: rw}\nbitsets:\n  f:\n    object: 0x6001\n"
      "    bits:\n      br: {bit: 30, width: 2, values: {0b100: on}}\n",
      "t.yaml:11:40: value code '0b100' does not fit in 2 bits");
}

TEST(ProfileLoaderErrors, ObjectsSubsAndArrays) {
  EXPECT_ERROR("  - {index: 0x6005, sub: 256, name: a, type: UNSIGNED8, access: ro}\n",
               "t.yaml:6:26: sub 256 is outside 0..255");
  EXPECT_ERROR("  - {index: 0x6005, sub: 1, name: a, type: UNSIGNED8, access: ro}\n"
               "  - {index: 0x6005, sub: 1, name: b, type: UNSIGNED8, access: ro}\n",
               "t.yaml:7:13: object 6005h sub 1 is defined twice");
  EXPECT_ERROR("  - {index: 0x6001, sub: 1, name: a, type: UNSIGNED8, access: ro, array: 4}\n",
               "t.yaml:6:26: an array defines its subs (0 and 1..4): drop sub");
  // An explicit sub colliding with a generated element.
  EXPECT_ERROR("  - {index: 0x6001, name: a, type: UNSIGNED8, access: ro, array: 4}\n"
               "  - {index: 0x6001, sub: 4, name: b, type: UNSIGNED8, access: ro}\n",
               "t.yaml:7:13: object 6001h sub 4 is defined twice");
  EXPECT_ERROR("  - {index: 0x6001, name: a, type: UNSIGNED8, access: ro, array: 4}\n"
               "  - {index: 0x6002, name: a_3, type: UNSIGNED8, access: ro}\n",
               "t.yaml:7:27: duplicate object name 'a_3'");
}

TEST(ProfileLoaderErrors, BitSetObjects) {
  const std::string objects =
      "  - {index: 0x6005, sub: 1, name: supported, type: UNSIGNED16, access: ro}\n"
      "  - {index: 0x1008, name: device_name, type: VISIBLE_STRING, access: ro}\nbitsets:\n  s:\n";
  EXPECT_ERROR(objects + "    object: 0x6005\n    sub: 3\n    bits: {a: 0}\n",
               "t.yaml:11:10: bitset s names an object the profile does not define");
  EXPECT_ERROR(objects + "    object: 0x1008\n    bits: {a: 0}\n",
               "t.yaml:10:13: bitset s needs an integer object, not VISIBLE_STRING");
  EXPECT_ERROR(objects + "    object: 0x6005\n    sub: 1\n    bitz: {a: 0}\n",
               "t.yaml:12:5: unknown key 'bitz' in bitset s (allowed: object, sub, bits, enabling, stopping)");
}

TEST(ProfileLoaderErrors, Pdos) {
  const std::string objects = "  - {index: 0x6000, name: a, type: UNSIGNED32, access: ro}\n"
                              "  - {index: 0x6001, name: b, type: UNSIGNED32, access: wo}\npdos:\n";
  EXPECT_ERROR(objects + "  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, valid: maybe, mapping: "
                         "[0x60000020]}\n",
               "t.yaml:9:78: valid must be true, false or either (COB-ID bit 31 as the device starts), not 'maybe'");
  EXPECT_ERROR(objects +
                   "  - {name: rpdo1, direction: rx, cob_id: 0x200, transmission_type: 1, mapping: [0x60000020]}\n",
               "t.yaml:9:81: an RPDO cannot carry a, which is ro");
  EXPECT_ERROR(objects +
                   "  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60010020]}\n",
               "t.yaml:9:81: a TPDO cannot carry b, which is write-only");
  EXPECT_ERROR(objects +
                   "  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60000020],\n"
                   "     manufacturer_data: {name: extra, bits: 33}}\n",
               "t.yaml:10:45: manufacturer data of 33 bits does not fit: the mapping uses 32 of 64 bits");
  EXPECT_ERROR(objects +
                   "  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60000020],\n"
                   "     manufacturer_data: {name: Extra, bits: 16}}\n",
               "t.yaml:10:32: manufacturer_data name 'Extra' must be snake_case (a-z, 0-9, _; starting with a letter)");
  EXPECT_ERROR(objects +
                   "  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60000020],\n"
                   "     manufacturer_data: {name: extra}}\n",
               "t.yaml:10:25: manufacturer_data: missing required key 'bits'");
  EXPECT_ERROR(objects + "  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60000020], "
                         "mandatory: 2}\n",
               "t.yaml:9:105: 'mandatory' has a value of the wrong type: '2'");
}

TEST(ProfileLoaderErrors, PdoNamesAndAccess) {
  const std::string objects = "  - {index: 0x6000, name: a, type: UNSIGNED32, access: ro}\npdos:\n";
  const std::string pdo = "  - {name: tpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60000020]";
  EXPECT_ERROR(objects +
                   "  - {name: status, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60000020]}\n",
               "t.yaml:8:12: a TPDO is named tpdo1..tpdo512 (its CiA 301 number), not 'status'");
  EXPECT_ERROR(objects +
                   "  - {name: rpdo1, direction: tx, cob_id: 0x180, transmission_type: 1, mapping: [0x60000020]}\n",
               "t.yaml:8:12: a TPDO is named tpdo1..tpdo512 (its CiA 301 number), not 'rpdo1'");
  EXPECT_ERROR(objects + pdo + ", access: {mapping: sometimes}}\n",
               "t.yaml:8:112: access of mapping must be rw, rw_preop, const or ro, not 'sometimes'");
  EXPECT_ERROR(objects + pdo + ", access: {mapping: none}}\n",
               "t.yaml:8:112: access of mapping must be rw, rw_preop, const or ro, not 'none'");
  EXPECT_ERROR(objects + pdo + ", mapping_counts: [0, 3]}\n",
               "t.yaml:8:110: mapping_counts: 3 entries, but the PDO has 1 default and 0 manufacturer-specific ones");
  const auto p = load(
      objects.substr(0, objects.size() - 6) + "pdos:\n" + pdo +
      ",\n     access: {cob_id: valid_bit, inhibit_time: none, mapping_count: rw_preop, mapping: const},\n"
      "     mapping_counts: [0, 1, 2], manufacturer_entries: 1}\n");
  const auto& r = p.pdo("tpdo1")->rules;
  EXPECT_EQ(r.cob_id, lb::profiles::PdoAccess::valid_bit);
  EXPECT_EQ(r.transmission_type, lb::profiles::PdoAccess::rw);  // not given: CiA 301's rw
  EXPECT_EQ(r.inhibit_time, lb::profiles::PdoAccess::none);
  EXPECT_EQ(r.event_timer, lb::profiles::PdoAccess::rw);
  EXPECT_EQ(r.mapping_count, lb::profiles::PdoAccess::rw_preop);
  EXPECT_EQ(r.mapping, lb::profiles::PdoAccess::fixed);
  EXPECT_EQ(r.mapping_counts, (std::vector<std::uint8_t>{0, 1, 2}));
  EXPECT_EQ(r.manufacturer_entries, 1u);
  EXPECT_EQ(p.pdo("tpdo1")->communication_index(), 0x1800);
  EXPECT_EQ(p.pdo("tpdo1")->mapping_index(), 0x1A00);
}

// The built-in profiles' PDO access, against the specs' tables written out by hand: what a
// master may write decides what the bridge's boot writes and what it refuses.
TEST(BuiltinProfiles, PdoAccessAsTheSpecTablesSay) {
  using A = lb::profiles::PdoAccess;
  const auto registry = lb::profiles::ProfileRegistry::builtin();
  struct Row {
    const char* profile;
    const char* version;
    const char* pdo;
    A cob_id, type, mapping_count, mapping;
    std::vector<std::uint8_t> counts;
    unsigned manufacturer;
    std::uint16_t comm, map;
  };
  const Row rows[] = {
      // CiA 420-4 3.1 tables 3/5, 7/9, 11/13.
      {"cia420-4", "3.1", "tpdo1", A::fixed, A::rw, A::rw_preop, A::fixed, {0, 2, 3}, 1, 0x1800, 0x1A00},
      {"cia420-4", "3.1", "tpdo2", A::fixed, A::rw, A::fixed, A::fixed, {}, 0, 0x1801, 0x1A01},
      {"cia420-4", "3.1", "rpdo1", A::fixed, A::rw, A::fixed, A::fixed, {}, 0, 0x1400, 0x1600},
      // CiA 420-3 3.1: TPDO1 COB-ID rw but only valid / not valid; 1A00h sub 0 00h, 03h..04h.
      {"cia420-3", "3.1", "tpdo1", A::valid_bit, A::rw, A::rw_preop, A::fixed, {0, 3, 4}, 1, 0x1800, 0x1A00},
      {"cia420-3", "3.1", "tpdo2", A::fixed, A::rw, A::fixed, A::fixed, {}, 0, 0x1801, 0x1A01},
      {"cia420-3", "3.1", "rpdo1", A::fixed, A::rw, A::rw_preop, A::fixed, {0, 2, 3}, 1, 0x1400, 0x1600},
      // CiA 420-2 1.0 and 420-4 1.0 section 2: COB-ID ro, transmission type rw, mapping not restricted.
      {"cia420-2", "1.0", "tpdo2", A::fixed, A::rw, A::rw, A::rw, {}, 0, 0x1801, 0x1A01},
      {"cia420-4", "1.0", "rpdo1", A::fixed, A::rw, A::rw, A::rw, {}, 0, 0x1400, 0x1600},
      // CiA 414-2 4.2-4.6: COB-IDs and transmission types rw, mappings constant.
      {"cia414-2", "1.1", "rpdo3", A::rw, A::rw, A::fixed, A::fixed, {}, 0, 0x1402, 0x1602},
      {"cia414-2", "1.1", "tpdo1", A::rw, A::rw, A::fixed, A::fixed, {}, 0, 0x1800, 0x1A00},
  };
  for (const auto& row : rows) {
    SCOPED_TRACE(std::string(row.profile) + "@" + row.version + " " + row.pdo);
    const auto* profile = registry.find(row.profile, row.version);
    ASSERT_NE(profile, nullptr);
    const auto* pdo = profile->pdo(row.pdo);
    ASSERT_NE(pdo, nullptr);
    EXPECT_EQ(pdo->rules.cob_id, row.cob_id);
    EXPECT_EQ(pdo->rules.transmission_type, row.type);
    EXPECT_EQ(pdo->rules.mapping_count, row.mapping_count);
    EXPECT_EQ(pdo->rules.mapping, row.mapping);
    EXPECT_EQ(pdo->rules.mapping_counts, row.counts);
    EXPECT_EQ(pdo->rules.manufacturer_entries, row.manufacturer);
    EXPECT_EQ(pdo->communication_index(), row.comm);
    EXPECT_EQ(pdo->mapping_index(), row.map);
  }
  // A feeder RPDO's communication parameter has sub 0 = 02h: no inhibit time, no event timer.
  const auto* rpdo1 = registry.find("cia414-2", "1.1")->pdo("rpdo1");
  EXPECT_EQ(rpdo1->rules.inhibit_time, A::none);
  EXPECT_EQ(rpdo1->rules.event_timer, A::none);
}

// Hostile profile files (issue 12): each was accepted silently or aborted the process before.
TEST(ProfileLoaderHostile, DuplicateAndNonScalarKeysAreRefusedWithTheirPlace) {
  // An object's index given twice: yaml-cpp kept one of them without a word.
  EXPECT_ERROR("  - {index: 0x6030, index: 0x6031, name: s, type: UNSIGNED16, access: ro}\n",
               "t.yaml:6:21: key 'index' is given twice in this mapping (first at line 6, column 6)");
  // A list as a key threw YAML::TypedBadConversion out of the loader (exit 134 in every executable).
  EXPECT_ERROR(kBitsetHead + "      ? [a, b]\n      : 1\n", "t.yaml:11:9: a key must be a plain value, not a list");
  EXPECT_ERROR("  - {index: 0x6030, name: s, type: UNSIGNED8, access: ro, values: {? [1, 2] : x}}\n",
               "t.yaml:6:70: a key must be a plain value, not a list");
}

TEST(ProfileLoaderHostile, OnlyRegularFilesOfBoundedSizeAreRead) {
  auto registry = lb::profiles::ProfileRegistry::builtin();
  auto r = registry.add_file("/dev/zero");  // was read without end
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().message, "/dev/zero: profile file: not a regular file");
  const std::string big = ::testing::TempDir() + "/profile_big_" + std::to_string(::getpid()) + ".yaml";
  {
    std::ofstream out(big);
    out << kHeader << "  - {index: 0x6030, name: status_word, type: UNSIGNED16, access: ro}\n";
    for (int i = 0; i < 50'000; ++i) out << "# " << std::string(100, '-') << "\n";
  }
  r = registry.add_file(big);
  std::remove(big.c_str());
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("larger than 4194304 bytes"), std::string::npos) << r.error().message;
}

// Found by fuzz_profile: a PDO's cob_id is the base the node-ID is added to; 7FFh was accepted and
// gave node 127 the identifier 87Eh, which no 11-bit frame can carry (the bus loop threw on it).
TEST(ProfileLoaderHostile, APdoBasePlusAnyNodeIdIsAnElevenBitIdentifier) {
  const std::string objects = "  - {index: 0x6000, name: a, type: UNSIGNED32, access: ro}\npdos:\n";
  EXPECT_ERROR(objects +
                   "  - {name: tpdo1, direction: tx, cob_id: 0x7FF, transmission_type: 1, mapping: [0x60000020]}\n",
               "t.yaml:8:42: cob_id 2047 is outside 1..1920");
  EXPECT_ERROR(objects +
                   "  - {name: tpdo1, direction: tx, cob_id: 0x781, transmission_type: 1, mapping: [0x60000020]}\n",
               "t.yaml:8:42: cob_id 1921 is outside 1..1920");
  const auto p = load(objects +
                      "  - {name: tpdo1, direction: tx, cob_id: 0x780, transmission_type: 1, mapping: [0x60000020]}\n");
  ASSERT_EQ(p.pdos.size(), 1u);
  EXPECT_EQ(p.pdos[0].cob_id(127), 0x7FFu);
}
