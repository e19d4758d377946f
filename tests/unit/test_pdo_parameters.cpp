// How the master takes a device's PDO from what it has to what the line wants: the CiA 301 write
// sequence where the profile lets a master write, a refusal naming the entry and both values
// where it does not, read-back verification, and adopt mode. Rules and values are written here by
// hand from the spec tables (CiA 420-4 3.1 tables 2-13, CiA 420-2 1.0 section 2).
#include <gtest/gtest.h>

#include "canopen/pdo_parameters.hpp"

using namespace lb::canopen;

namespace {

// A PDO the line wants: its name, its communication (1400h../1800h..: a TPDO's from 1800h) and
// mapping objects and the parameters; the CiA 301 rules (all rw) unless a test gives the profile's.
PdoSpec pdo_spec(std::string name, std::uint16_t communication, std::uint16_t mapping, PdoParameters wanted) {
  PdoSpec s;
  s.name = std::move(name);
  s.transmit = communication >= 0x1800;
  s.communication_index = communication;
  s.mapping_index = mapping;
  s.wanted = std::move(wanted);
  return s;
}

// Saw 3.1 TPDO2 (1801h/1A01h): COB-ID const, transmission type rw, mapping const.
PdoSpec saw_tpdo2() {
  PdoSpec s = pdo_spec("tpdo2", 0x1801, 0x1A01,
                       {0x285, 1, 0, 0, {PdoEntry::from_u32(0x60010020), PdoEntry::from_u32(0x60070020)}});
  s.rules = {PdoAccess::fixed, PdoAccess::rw, PdoAccess::rw, PdoAccess::rw, PdoAccess::fixed, PdoAccess::fixed, {}, 0};
  return s;
}

// Saw 3.1 TPDO1 (1800h/1A00h): sub 0 rw while not operational, 00h or 02h..03h; sub 3 manufacturer's.
PdoSpec saw_tpdo1() {
  PdoSpec s = pdo_spec("tpdo1", 0x1800, 0x1A00,
                       {0x185, 1, 0, 0, {PdoEntry::from_u32(0x60300010), PdoEntry::from_u32(0x60000020)}});
  s.rules = {PdoAccess::fixed,    PdoAccess::rw,    PdoAccess::rw, PdoAccess::rw,
             PdoAccess::rw_preop, PdoAccess::fixed, {0, 2, 3},     1};
  return s;
}

// Puller 1.0 TPDO2 (1801h/1A01h): COB-ID ro, the rest CiA 301 rw.
PdoSpec puller_tpdo2() {
  PdoSpec s = pdo_spec("tpdo2", 0x1801, 0x1A01,
                       {0x286, 1, 0, 0, {PdoEntry::from_u32(0x60040010), PdoEntry::from_u32(0x60080020)}});
  s.rules.cob_id = PdoAccess::fixed;
  return s;
}

DevicePdo device(std::uint32_t cob_id, std::uint8_t type, std::vector<std::uint32_t> mapping,
                 std::vector<std::uint32_t> unmapped = {}) {
  DevicePdo d;
  d.parameters.cob_id = cob_id;
  d.parameters.transmission_type = type;
  for (auto e : mapping) d.parameters.mapping.push_back(PdoEntry::from_u32(e));
  for (auto e : unmapped) d.unmapped.push_back(PdoEntry::from_u32(e));
  return d;
}

struct W {
  std::uint16_t index;
  std::uint8_t sub;
  std::uint32_t value;
};

void expect_writes(const PdoPlan& plan, const std::vector<W>& expected) {
  ASSERT_EQ(plan.writes.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(plan.writes[i].index, expected[i].index) << "write " << i;
    EXPECT_EQ(plan.writes[i].sub, expected[i].sub) << "write " << i;
    EXPECT_EQ(plan.writes[i].value, expected[i].value) << "write " << i;
  }
}

}  // namespace

TEST(PdoPlan, DeviceThatMatchesGetsNoWrite) {
  // The device answers 4000 0285h (bit 30: no RTR), the line wants 285h: bit 30 is not compared.
  const auto plan = plan_pdo(saw_tpdo2(), device(0x40000285, 1, {0x60010020, 0x60070020}));
  ASSERT_TRUE(plan) << plan.error().message;
  EXPECT_TRUE(plan->writes.empty());
  EXPECT_FALSE(plan->needs_not_operational);
}

TEST(PdoPlan, TransmissionTypeIsWrittenWhereTheProfileAllows) {
  auto spec = saw_tpdo2();
  spec.wanted.transmission_type = 2;
  const auto plan = plan_pdo(spec, device(0x40000285, 1, {0x60010020, 0x60070020}));
  ASSERT_TRUE(plan) << plan.error().message;
  expect_writes(*plan, {{0x1801, 2, 2}});
  EXPECT_FALSE(plan->needs_not_operational);
  EXPECT_EQ(plan->result.transmission_type, 2);
}

TEST(PdoPlan, ConstMappingEntryIsRefusedWithBothValues) {
  // A line file that swaps saw 3.1 TPDO2's objects: 1A01h sub 1 is const (Table 9).
  auto spec = saw_tpdo2();
  spec.wanted.mapping = {PdoEntry::from_u32(0x60070020), PdoEntry::from_u32(0x60010020)};
  const auto plan = plan_pdo(spec, device(0x40000285, 1, {0x60010020, 0x60070020}));
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error().index, 0x1A01);
  EXPECT_EQ(plan.error().sub, 1);
  EXPECT_EQ(plan.error().expected, "6007 00 20h");
  EXPECT_EQ(plan.error().actual, "6001 00 20h");
  EXPECT_NE(plan.error().message.find("tpdo2"), std::string::npos) << plan.error().message;
  EXPECT_NE(plan.error().message.find("const"), std::string::npos) << plan.error().message;
}

TEST(PdoPlan, ConstCobIdIsRefused) {
  auto spec = saw_tpdo2();
  spec.wanted.cob_id = 0x20000285;  // 29-bit
  const auto plan = plan_pdo(spec, device(0x40000285, 1, {0x60010020, 0x60070020}));
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error().index, 0x1801);
  EXPECT_EQ(plan.error().sub, 1);
  EXPECT_NE(plan.error().actual.find("4000 0285h"), std::string::npos) << plan.error().actual;
}

TEST(PdoPlan, ManufacturerEntryIsMappedOrUnmappedBySubZeroAlone) {
  // Saw 3.1 TPDO1 with the manufacturer's third object mapped (sub 0 = 3): the line wants the
  // profile's two. Sub 0 is writable outside operational, the entries are not touched.
  const auto three = device(0x40000185, 1, {0x60300010, 0x60000020, 0x21100010});
  auto plan = plan_pdo(saw_tpdo1(), three);
  ASSERT_TRUE(plan) << plan.error().message;
  expect_writes(*plan, {{0x1A00, 0, 2}});
  EXPECT_TRUE(plan->needs_not_operational);

  // And back: sub 3 exists on the device (unmapped), so sub 0 = 3 maps it without writing it.
  auto spec = saw_tpdo1();
  spec.wanted.mapping.push_back(PdoEntry::from_u32(0x21100010));
  plan = plan_pdo(spec, device(0x40000185, 1, {0x60300010, 0x60000020}, {0x21100010}));
  ASSERT_TRUE(plan) << plan.error().message;
  expect_writes(*plan, {{0x1A00, 0, 3}});

  // A different third object cannot be written (const).
  spec.wanted.mapping.back() = PdoEntry::from_u32(0x21200010);
  plan = plan_pdo(spec, device(0x40000185, 1, {0x60300010, 0x60000020}, {0x21100010}));
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error().index, 0x1A00);
  EXPECT_EQ(plan.error().sub, 3);
}

TEST(PdoPlan, SubZeroOutsideTheProfilesRangeIsRefused) {
  auto spec = saw_tpdo1();
  spec.wanted.mapping.resize(1);  // 1A00h sub 0 = 1: the profile allows 00h, 02h to 03h
  const auto plan = plan_pdo(spec, device(0x40000185, 1, {0x60300010, 0x60000020}));
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error().index, 0x1A00);
  EXPECT_EQ(plan.error().sub, 0);
  EXPECT_NE(plan.error().message.find("0, 2, 3"), std::string::npos) << plan.error().message;
}

TEST(PdoPlan, WritableMappingFollowsTheCia301Sequence) {
  // Puller 1.0 TPDO2 remapped (product speed first): its COB-ID is ro, so the PDO cannot be made
  // invalid: sub 0 = 0, the entries, sub 0 = 2, in pre-operational.
  auto spec = puller_tpdo2();
  spec.wanted.mapping = {PdoEntry::from_u32(0x60080020), PdoEntry::from_u32(0x60040010)};
  const auto plan = plan_pdo(spec, device(0x40000286, 1, {0x60040010, 0x60080020}));
  ASSERT_TRUE(plan) << plan.error().message;
  expect_writes(*plan, {{0x1A01, 0, 0}, {0x1A01, 1, 0x60080020}, {0x1A01, 2, 0x60040010}, {0x1A01, 0, 2}});
  EXPECT_TRUE(plan->needs_not_operational);
}

TEST(PdoPlan, WritableCobIdIsInvalidatedAroundAMappingChange) {
  // CiA 301: COB-ID bit 31 set, sub 0 = 0, entries, sub 0 = n, parameters, COB-ID valid again.
  auto spec = puller_tpdo2();
  spec.rules.cob_id = PdoAccess::rw;
  spec.wanted.mapping = {PdoEntry::from_u32(0x60080020)};
  spec.wanted.transmission_type = 254;
  spec.wanted.inhibit_time = 500;
  spec.wanted.event_timer = 300;
  spec.wanted.cob_id = 0x20000286;  // and a 29-bit identifier
  const auto plan = plan_pdo(spec, device(0x40000286, 1, {0x60040010, 0x60080020}));
  ASSERT_TRUE(plan) << plan.error().message;
  expect_writes(*plan, {{0x1801, 1, 0xC0000286},
                        {0x1A01, 0, 0},
                        {0x1A01, 1, 0x60080020},
                        {0x1A01, 0, 1},
                        {0x1801, 2, 254},
                        {0x1801, 3, 500},
                        {0x1801, 5, 300},
                        {0x1801, 1, 0x60000286}});  // valid, bit 30 kept as the device had it, 29-bit
}

TEST(PdoPlan, ValidBitAloneMayChangeWhereOnlyItIsWritable) {
  // Corrugator 3.1 TPDO1: COB-ID rw, but only 4000 0180h + n or C000 0180h + n.
  auto spec = pdo_spec("tpdo1", 0x1800, 0x1A00, {0x80000187, 1, 0, 0, {PdoEntry::from_u32(0x60300010)}});
  spec.rules.cob_id = PdoAccess::valid_bit;
  auto plan = plan_pdo(spec, device(0x40000187, 1, {0x60300010}));
  ASSERT_TRUE(plan) << plan.error().message;
  expect_writes(*plan, {{0x1800, 1, 0xC0000187}});
  spec.wanted.cob_id = 0x190;  // another identifier: refused
  EXPECT_FALSE(plan_pdo(spec, device(0x40000187, 1, {0x60300010})));
}

TEST(PdoPlan, EitherValidityTakesTheDevicesBit) {
  // Feeder TPDO1: the device may start it valid or not; the line does not say.
  auto spec = pdo_spec("tpdo1", 0x1800, 0x1A00, {0x182, 255, 0, 0, {PdoEntry::from_u32(0x60100020)}});
  spec.validity_given = false;
  spec.rules.mapping = spec.rules.mapping_count = PdoAccess::fixed;
  const auto plan = plan_pdo(spec, device(0xC0000182, 255, {0x60100020}));
  ASSERT_TRUE(plan) << plan.error().message;
  EXPECT_TRUE(plan->writes.empty());
  EXPECT_FALSE(plan->result.valid());
}

TEST(PdoPlan, MissingTimingEntryIsAMismatch) {
  auto spec = saw_tpdo2();
  spec.wanted.inhibit_time = 100;
  auto d = device(0x40000285, 1, {0x60010020, 0x60070020});
  d.has_inhibit_time = false;
  const auto plan = plan_pdo(spec, d);
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error().sub, 3);
  EXPECT_EQ(plan.error().actual, "absent");
}

TEST(PdoPlan, RpdoTimingIsTheMastersAndNotCompared) {
  auto spec = pdo_spec("rpdo1", 0x1400, 0x1600, {0x205, 1, 500, 300, {PdoEntry::from_u32(0x60200010)}});
  const auto plan = plan_pdo(spec, device(0x205, 1, {0x60200010}));
  ASSERT_TRUE(plan) << plan.error().message;
  EXPECT_TRUE(plan->writes.empty());
}

TEST(PdoPlan, AdoptTakesTheDevicesMappingAndTypeButNotItsIdentifier) {
  const auto d = device(0x40000285, 2, {0x60070020, 0x60010020});
  const auto adopted = adopt_device_pdo(saw_tpdo2(), d);
  const auto plan = plan_pdo(adopted, d);
  ASSERT_TRUE(plan) << plan.error().message;
  EXPECT_TRUE(plan->writes.empty());
  ASSERT_EQ(plan->result.mapping.size(), 2u);
  EXPECT_EQ(plan->result.mapping[0].index, 0x6007);
  EXPECT_EQ(plan->result.transmission_type, 2);

  auto other_id = device(0x40000295, 1, {0x60010020, 0x60070020});
  EXPECT_FALSE(plan_pdo(adopt_device_pdo(saw_tpdo2(), other_id), other_id)) << "the identifier is the line's";
}

TEST(PdoPlan, ReadBackCatchesAnIgnoredWrite) {
  auto spec = saw_tpdo2();
  spec.wanted.transmission_type = 2;
  const auto d = device(0x40000285, 1, {0x60010020, 0x60070020});
  const auto plan = plan_pdo(spec, d);
  ASSERT_TRUE(plan);
  // The device confirmed the write of 1801h sub 2 but still has 1.
  const auto m = verify_pdo(spec, plan->result, d);
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(m->index, 0x1801);
  EXPECT_EQ(m->sub, 2);
  EXPECT_EQ(m->expected, "2");
  EXPECT_EQ(m->actual, "1");
  auto done = d;
  done.parameters.transmission_type = 2;
  EXPECT_FALSE(verify_pdo(spec, plan->result, done).has_value());
}

TEST(PdoPlan, AbsentOptionalPdoIsNotUsed) {
  auto spec = saw_tpdo2();
  spec.optional = true;
  DevicePdo d;
  d.absent = true;
  const auto plan = plan_pdo(spec, d);
  ASSERT_TRUE(plan);
  EXPECT_TRUE(plan->writes.empty());
  EXPECT_FALSE(plan->result.valid());
}

// CiA 301: the inhibit time changes only while the PDO is not valid. Corrugator 3.1 TPDO1 (table
// 3: only the valid bit of its COB-ID is writable; inhibit time rw): an inhibit-time difference
// alone is written between COB-ID C000 0187h and 4000 0187h, and takes the PDO out of service.
TEST(PdoPlan, InhibitTimeAloneIsWrittenWhileThePdoIsNotValid) {
  auto spec = pdo_spec("tpdo1", 0x1800, 0x1A00, {0x187, 1, 100, 0, {PdoEntry::from_u32(0x60300010)}});
  spec.rules.cob_id = PdoAccess::valid_bit;
  const auto plan = plan_pdo(spec, device(0x40000187, 1, {0x60300010}));
  ASSERT_TRUE(plan) << plan.error().message;
  expect_writes(*plan, {{0x1800, 1, 0xC0000187}, {0x1800, 3, 100}, {0x1800, 1, 0x40000187}});
  EXPECT_FALSE(plan->needs_not_operational);
  ASSERT_TRUE(plan->disrupts);
  EXPECT_EQ(plan->disrupts->index, 0x1800);
  EXPECT_EQ(plan->disrupts->sub, 3);
  EXPECT_EQ(plan->disrupts->expected, "100");
  EXPECT_EQ(plan->disrupts->actual, "0");

  // A PDO the device has not valid: written as it is, made valid last; nothing to take out of service.
  const auto off = plan_pdo(spec, device(0xC0000187, 1, {0x60300010}));
  ASSERT_TRUE(off) << off.error().message;
  expect_writes(*off, {{0x1800, 3, 100}, {0x1800, 1, 0x40000187}});
  EXPECT_FALSE(off->disrupts);
}

// CiA 301 lets a master write the transmission type and the event timer of a valid PDO: no
// invalidation, and nothing a running device cannot take.
TEST(PdoPlan, TransmissionTypeAndEventTimerNeedNoInvalidation) {
  auto spec = puller_tpdo2();
  spec.rules.cob_id = PdoAccess::rw;
  spec.wanted.transmission_type = 254;
  spec.wanted.event_timer = 300;
  const auto plan = plan_pdo(spec, device(0x40000286, 1, {0x60040010, 0x60080020}));
  ASSERT_TRUE(plan) << plan.error().message;
  expect_writes(*plan, {{0x1801, 2, 254}, {0x1801, 5, 300}});
  EXPECT_FALSE(plan->disrupts);
}

// Saw 3.1 TPDO1/TPDO2: COB-ID const (tables 3, 7), so the PDO can never be made invalid and its
// inhibit time never written, whatever the table says of sub 3: refused with both values (the
// boot's J); adopt takes the device's value.
TEST(PdoPlan, InhibitTimeOfAPdoWhoseCobIdIsConstIsRefused) {
  auto spec = saw_tpdo2();
  spec.wanted.inhibit_time = 500;
  const auto d = device(0x40000285, 1, {0x60010020, 0x60070020});
  const auto plan = plan_pdo(spec, d);
  ASSERT_FALSE(plan);
  EXPECT_EQ(plan.error().index, 0x1801);
  EXPECT_EQ(plan.error().sub, 3);
  EXPECT_EQ(plan.error().expected, "500");
  EXPECT_EQ(plan.error().actual, "0");
  EXPECT_NE(plan.error().message.find("not valid"), std::string::npos) << plan.error().message;
  const auto adopted = adopt_device_pdo(spec, d);
  const auto kept = plan_pdo(adopted, d);
  ASSERT_TRUE(kept) << kept.error().message;
  EXPECT_TRUE(kept->writes.empty());
  EXPECT_EQ(kept->result.inhibit_time, 0);
}

// A mapping change takes the PDO out of service too (a running device keeps it only by pausing).
TEST(PdoPlan, MappingChangeDisruptsThePdo) {
  auto spec = puller_tpdo2();
  spec.wanted.mapping = {PdoEntry::from_u32(0x60080020), PdoEntry::from_u32(0x60040010)};
  const auto plan = plan_pdo(spec, device(0x40000286, 1, {0x60040010, 0x60080020}));
  ASSERT_TRUE(plan) << plan.error().message;
  ASSERT_TRUE(plan->disrupts);
  EXPECT_EQ(plan->disrupts->index, 0x1A01);
}
