// A device's active errors as CiA 301 has them: what an EMCY 0000h (error reset) may and may not
// clear, a boot-up, and what the device lists itself (1001h, 1003h). Codes and registers written
// by hand from CiA 301 (cia301-essentials.md, EMCY).
#include <gtest/gtest.h>

#include "canopen/emcy.hpp"
#include "canopen/error_field.hpp"

using lb::canopen::ActiveErrors;
using lb::canopen::Emergency;
using lb::canopen::ErrorFieldReading;

namespace {

Emergency emcy(std::uint16_t code, std::uint8_t error_register) {
  Emergency e;
  e.error_code = code;
  e.error_register = error_register;
  return e;
}

std::vector<std::uint16_t> codes(const ActiveErrors& a) { return a.codes(); }

}  // namespace

TEST(ActiveErrors, UnknownUntilTheDeviceSaysSomething) {
  ActiveErrors a;
  EXPECT_FALSE(a.known()) << "errors raised before the bridge listened cannot be known";
  EXPECT_TRUE(a.codes().empty());
  a.reset_by_boot_up();
  EXPECT_TRUE(a.known());
}

TEST(ActiveErrors, ErrorResetWithRegisterZeroClearsEverything) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x4210, 0x09));  // temperature: generic + temperature bits
  a.apply(emcy(0x3120, 0x05));  // voltage
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x4210, 0x3120}));
  EXPECT_EQ(a.error_register(), 0x05);
  a.apply(emcy(0x0000, 0x00));
  EXPECT_TRUE(a.codes().empty());
  EXPECT_TRUE(a.known());
  EXPECT_FALSE(a.needs_reading());
}

// CiA 301: an EMCY 0000h says "error reset or no error"; the register it carries says whether
// errors remain. With register 01h some do, and the EMCY does not say which.
TEST(ActiveErrors, ErrorResetWithErrorsRemainingMakesTheListUncertain) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x4210, 0x09));
  a.apply(emcy(0x3120, 0x0D));
  a.apply(emcy(0x0000, 0x05));  // 4210h cleared, 3120h (voltage) remains
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x4210, 0x3120})) << "nothing may be dropped on a guess";
  EXPECT_FALSE(a.known());
  EXPECT_TRUE(a.needs_reading());
  EXPECT_NE(a.note().find("error register 05h"), std::string::npos) << a.note();
  EXPECT_EQ(a.error_register(), 0x05);
}

TEST(ActiveErrors, BootUpClearsTheList) {
  ActiveErrors a;
  a.apply(emcy(0x5000, 0x01));
  a.apply(emcy(0x0000, 0x01));
  ASSERT_FALSE(a.known());
  a.reset_by_boot_up();
  EXPECT_TRUE(a.codes().empty());
  EXPECT_EQ(a.error_register(), 0);
  EXPECT_TRUE(a.known());
  EXPECT_FALSE(a.needs_reading());
}

TEST(ErrorField, TheDevicesOwnListReplacesTheUncertainOne) {
  ActiveErrors a;
  a.apply(emcy(0x4210, 0x09));
  a.apply(emcy(0x3120, 0x0D));
  a.apply(emcy(0x0000, 0x05));
  ErrorFieldReading r;
  r.error_register = 0x05;
  r.codes = std::vector<std::uint16_t>{0x3120};
  apply(a, r);
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x3120}));
  EXPECT_TRUE(a.known());
  EXPECT_NE(a.note().find("1003h"), std::string::npos) << a.note();
}

TEST(ErrorField, RegisterZeroMeansNoActiveErrorWhateverTheHistorySays) {
  ActiveErrors a;
  a.apply(emcy(0x4210, 0x09));
  ErrorFieldReading r;
  r.error_register = 0;
  apply(a, r);
  EXPECT_TRUE(a.codes().empty());
  EXPECT_TRUE(a.known());
}

TEST(ErrorField, WithoutAn1003hTheListStaysUncertainAndSaysWhy) {
  ActiveErrors a;
  a.apply(emcy(0x4210, 0x09));
  a.apply(emcy(0x0000, 0x01));
  ErrorFieldReading r;
  r.error_register = 0x01;  // no codes: the device has no 1003h
  apply(a, r);
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x4210}));
  EXPECT_FALSE(a.known());
  EXPECT_NE(a.note().find("no 1003h"), std::string::npos) << a.note();
  EXPECT_EQ(a.error_register(), 0x01);
}

TEST(ErrorField, AFailedReadKeepsTheListAndSaysSo) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x4210, 0x09));
  ErrorFieldReading r;
  r.error = lb::canopen::SdoError{0x05040000, "timed out"};
  apply(a, r);
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x4210}));
  EXPECT_FALSE(a.known());
  EXPECT_NE(a.note().find("could not be read"), std::string::npos) << a.note();
}
