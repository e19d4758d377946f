// PDO codec: CiA 301 packing (LSB first, in mapping order, no padding), length rules.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <vector>

#include "canopen/data_type.hpp"
#include "canopen/pdo_mapping.hpp"
#include "canopen/process_image.hpp"

using lb::canopen::PdoEntry;
using lb::canopen::PdoMapping;

namespace {

PdoMapping mapping(std::vector<std::uint32_t> entries) {
  std::vector<PdoEntry> e;
  for (auto v : entries) e.push_back(PdoEntry::from_u32(v));
  auto m = PdoMapping::create(e);
  EXPECT_TRUE(m.has_value());
  return *m;
}

}  // namespace

TEST(PdoEntry, ThirtyTwoBitFormIsIndexSubLength) {
  const auto e = PdoEntry::from_u32(0x60300010);
  EXPECT_EQ(e.index, 0x6030);
  EXPECT_EQ(e.sub, 0x00);
  EXPECT_EQ(e.bits, 16);
  EXPECT_EQ(e.to_u32(), 0x60300010u);
  EXPECT_TRUE(PdoEntry::from_u32(0x00050008).is_dummy());
  EXPECT_FALSE(e.is_dummy());
}

TEST(PdoMapping, UnpacksLittleEndianInMappingOrder) {
  // Saw TPDO1: 6030h (16) then 6000h (32).
  const auto m = mapping({0x60300010, 0x60000020});
  EXPECT_EQ(m.total_bits(), 48u);
  EXPECT_EQ(m.byte_length(), 6u);
  const std::array<std::uint8_t, 6> frame{0x34, 0x12, 0x78, 0x56, 0x34, 0x12};
  PdoMapping::Values v{};
  ASSERT_TRUE(m.unpack(frame, v));
  EXPECT_EQ(v[0], 0x1234u);
  EXPECT_EQ(v[1], 0x12345678u);
}

TEST(PdoMapping, PacksExactBytes) {
  // Saw RPDO1: control word 0005h, sync speed 5000 (1388h), length 12345 (3039h).
  const auto m = mapping({0x60200010, 0x60050010, 0x60020020});
  std::array<std::uint8_t, 8> out{};
  const std::array<std::uint64_t, 3> values{0x0005, 5000, 12345};
  EXPECT_EQ(m.pack(values, out), 8);
  EXPECT_EQ(out, (std::array<std::uint8_t, 8>{0x05, 0x00, 0x88, 0x13, 0x39, 0x30, 0x00, 0x00}));
}

TEST(PdoMapping, BitFieldsAndDummiesAreNotByteAligned) {
  // 1 bit, a 3-bit dummy gap, 4 bits, then 8 bits: two bytes.
  const auto m = mapping({0x20000101, 0x00010003, 0x20000204, 0x20000308});
  EXPECT_EQ(m.byte_length(), 2u);
  const std::array<std::uint8_t, 2> frame{0b1010'0001, 0xC3};
  PdoMapping::Values v{};
  ASSERT_TRUE(m.unpack(frame, v));
  EXPECT_EQ(v[0], 1u);
  EXPECT_EQ(v[2], 0b1010u);
  EXPECT_EQ(v[3], 0xC3u);
  std::array<std::uint8_t, 8> out{};
  const std::array<std::uint64_t, 4> values{1, 0x7 /* dummy: masked to its 3 bits, still written */, 0b1010, 0xC3};
  EXPECT_EQ(m.pack(values, out), 2);
  EXPECT_EQ(out[0], 0b1010'1111);
  EXPECT_EQ(out[1], 0xC3);
}

TEST(PdoMapping, SixtyFourBitEntryUsesWholeFrame) {
  const auto m = mapping({0x20000140});
  const std::array<std::uint8_t, 8> frame{1, 2, 3, 4, 5, 6, 7, 0x88};
  PdoMapping::Values v{};
  ASSERT_TRUE(m.unpack(frame, v));
  EXPECT_EQ(v[0], 0x8807060504030201u);
}

TEST(PdoMapping, ShortPayloadIsRefusedAndOutputUntouched) {
  const auto m = mapping({0x60300010, 0x60000020});
  const std::array<std::uint8_t, 5> frame{1, 2, 3, 4, 5};
  PdoMapping::Values v{};
  v[0] = 0xDEAD;
  const auto r = m.unpack(frame, v);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("5 bytes"), std::string::npos) << r.error().message;
  EXPECT_EQ(v[0], 0xDEADu);
}

TEST(PdoMapping, LongerPayloadIsAllowed) {
  const auto m = mapping({0x60300010});
  const std::array<std::uint8_t, 4> frame{0x01, 0x80, 0xFF, 0xFF};
  PdoMapping::Values v{};
  ASSERT_TRUE(m.unpack(frame, v));
  EXPECT_EQ(v[0], 0x8001u);
}

TEST(PdoMapping, RefusesMappingsACanFrameCannotCarry) {
  EXPECT_FALSE(PdoMapping::create(
      {PdoEntry::from_u32(0x60000020), PdoEntry::from_u32(0x60010020), PdoEntry::from_u32(0x60020008)}));
  EXPECT_FALSE(PdoMapping::create({PdoEntry::from_u32(0x60000000)}));
}

TEST(DataType, SignExtension) {
  EXPECT_EQ(lb::canopen::sign_extend(0xFFFF, 16), -1);
  EXPECT_EQ(lb::canopen::sign_extend(0x7FFF, 16), 32767);
  EXPECT_EQ(lb::canopen::sign_extend(0xFFFFFFF6, 32), -10);
  EXPECT_EQ(lb::canopen::type_max(lb::canopen::DataType::unsigned16), 65535u);
  EXPECT_EQ(lb::canopen::type_min(lb::canopen::DataType::integer32), -2147483648LL);
}

TEST(PdoBinding, UnknownEntriesAreSkippedAndSentAsZero) {
  lb::canopen::ProcessImage image;
  const auto status = image.slot(0x6030);
  const lb::canopen::PdoBinding binding(mapping({0x60300010, 0x20010010}), image);
  const std::array<std::uint8_t, 4> frame{0x02, 0x00, 0xAA, 0xBB};
  ASSERT_TRUE(binding.unpack_into(frame, image));
  EXPECT_EQ(image.get(status), 2u);
  std::array<std::uint8_t, 8> out{};
  EXPECT_EQ(binding.pack_from(image, out), 4);
  EXPECT_EQ(out[0], 0x02);
  EXPECT_EQ(out[2], 0x00);
  EXPECT_EQ(out[3], 0x00);
}
