// A device's active errors as CiA 301 has them: what an EMCY 0000h (error reset) may and may not
// clear, what an error register of 0 says, a boot-up, and what the master reads from the device:
// 1001h (the error register) reconciles the list; 1003h (the pre-defined error field) is the
// device's error HISTORY and never feeds it. Codes and registers written by hand from CiA 301
// (cia301-essentials.md, EMCY; node-state-machine.md, "Errors: history versus active list").
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

// 1003h as a master reads it: entries newest first (sub 1 = the newest).
ErrorFieldReading reading(std::uint8_t error_register, std::vector<std::uint32_t> history_newest_first) {
  ErrorFieldReading r;
  r.error_register = error_register;
  r.history.read = true;
  r.history.count = static_cast<std::uint8_t>(history_newest_first.size());
  r.history.entries = std::move(history_newest_first);
  return r;
}

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
}

// CiA 301: the error register is 0 when no error is active. An EMCY that carries a code with
// register 0 reports an event, not an error that stays (and it ends whatever was listed).
TEST(ActiveErrors, AnEmcyWithErrorRegisterZeroLeavesNoErrorActive) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x4210, 0x09));
  a.apply(emcy(0x8210, 0x00));  // PDO not processed (length), register 0
  EXPECT_TRUE(a.codes().empty());
  EXPECT_TRUE(a.known());
  EXPECT_EQ(a.error_register(), 0x00);
}

// CiA 301: an EMCY 0000h says "error reset or no error"; the register it carries says whether
// errors remain. With register 05h some do, and the EMCY does not say which.
TEST(ActiveErrors, ErrorResetWithErrorsRemainingMakesTheListUncertain) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x4210, 0x09));
  a.apply(emcy(0x3120, 0x0D));
  a.apply(emcy(0x0000, 0x05));  // 4210h cleared, 3120h (voltage) remains
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x4210, 0x3120})) << "nothing may be dropped on a guess";
  EXPECT_FALSE(a.known());
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
}

// 1003h after 4210h, 3120h and an error reset that left the voltage error: the history holds all
// three EMCYs (0000h newest). It says what happened, not what is active: the list stays as the
// EMCYs left it, uncertain, and never lists 0000h or an entry of the history it did not have.
TEST(ErrorField, TheHistoryIsNotTheActiveList) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x4210, 0x09));
  a.apply(emcy(0x3120, 0x0D));
  a.apply(emcy(0x0000, 0x05));
  apply(a, reading(0x05, {0x0000, 0x3120, 0x4210, 0x5000}));
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x4210, 0x3120}));
  EXPECT_FALSE(a.known());
  EXPECT_NE(a.note().find("EMCY 0000h"), std::string::npos) << "the reason stays the error reset: " << a.note();
  EXPECT_EQ(a.error_register(), 0x05);
}

TEST(ErrorField, RegisterZeroMeansNoActiveErrorWhateverTheHistorySays) {
  ActiveErrors a;
  a.apply(emcy(0x4210, 0x09));
  apply(a, reading(0x00, {0x4210, 0x3120}));
  EXPECT_TRUE(a.codes().empty());
  EXPECT_TRUE(a.known());
  EXPECT_EQ(a.error_register(), 0x00);
}

// Errors raised before the bridge heard the device (no boot-up seen), or since a boot-up without an
// EMCY naming them: 1001h says some are active, and only the history names codes, which may long
// be cleared. The list stays empty and says it is uncertain, and why.
TEST(ErrorField, ARegisterThatReportsErrorsNoEmcyNamedMakesTheListUncertain) {
  ActiveErrors before_boot_up;
  apply(before_boot_up, reading(0x01, {0x5000}));
  EXPECT_TRUE(before_boot_up.codes().empty()) << "5000h is history, not an active error";
  EXPECT_FALSE(before_boot_up.known());
  EXPECT_EQ(before_boot_up.error_register(), 0x01);
  EXPECT_NE(before_boot_up.note().find("1001h = 01h"), std::string::npos) << before_boot_up.note();

  ActiveErrors after_boot_up;
  after_boot_up.reset_by_boot_up();
  apply(after_boot_up, reading(0x01, {0x0000, 0x5000}));
  EXPECT_TRUE(after_boot_up.codes().empty());
  EXPECT_FALSE(after_boot_up.known());
  EXPECT_NE(after_boot_up.note().find("1001h = 01h"), std::string::npos) << after_boot_up.note();
}

// Since the boot-up the EMCYs named 4210h; 1001h = 09h agrees: the list is known, with or without
// a 1003h on the device.
TEST(ErrorField, EmcysSinceTheBootUpStayTrueWhenTheRegisterReportsErrors) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x4210, 0x09));
  ErrorFieldReading r;
  r.error_register = 0x09;  // no history: the device has no 1003h
  apply(a, r);
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x4210}));
  EXPECT_TRUE(a.known()) << a.note();
  EXPECT_EQ(a.error_register(), 0x09);
}

// The register is only a check of what the EMCYs since the boot-up said: a read that failed does
// not make them wrong. A list not known for want of a boot-up says the read failed too.
TEST(ErrorField, AFailedReadKeepsTheListAndSaysSoWhereItWasNotKnown) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x4210, 0x09));
  ErrorFieldReading r;
  r.error = lb::canopen::SdoError{0x05040000, "timed out"};
  apply(a, r);
  EXPECT_EQ(codes(a), (std::vector<std::uint16_t>{0x4210}));
  EXPECT_TRUE(a.known());

  ActiveErrors never_booted;
  never_booted.apply(emcy(0x4210, 0x09));
  apply(never_booted, r);
  EXPECT_EQ(codes(never_booted), (std::vector<std::uint16_t>{0x4210}));
  EXPECT_FALSE(never_booted.known());
  EXPECT_NE(never_booted.note().find("could not be read"), std::string::npos) << never_booted.note();
}

// The classes diagnostics and /metrics count EMCYs by: CiA 301's table of error codes, by high
// byte (cia301-essentials.md, EMCY), with the codes written by hand.
TEST(EmcyClass, ByTheCodesHighByteAsCiA301GroupsThem) {
  using lb::canopen::emcy_class;
  using lb::canopen::EmcyClass;
  EXPECT_EQ(emcy_class(0x0000), EmcyClass::error_reset);
  EXPECT_EQ(emcy_class(0x1000), EmcyClass::generic);
  EXPECT_EQ(emcy_class(0x2310), EmcyClass::current);
  EXPECT_EQ(emcy_class(0x3210), EmcyClass::voltage);
  EXPECT_EQ(emcy_class(0x4210), EmcyClass::temperature);
  EXPECT_EQ(emcy_class(0x5000), EmcyClass::device_hardware);
  EXPECT_EQ(emcy_class(0x6100), EmcyClass::device_software);
  EXPECT_EQ(emcy_class(0x7000), EmcyClass::additional_modules);
  EXPECT_EQ(emcy_class(0x8130), EmcyClass::communication);
  EXPECT_EQ(emcy_class(0x8210), EmcyClass::protocol);
  EXPECT_EQ(emcy_class(0x8611), EmcyClass::monitoring);
  EXPECT_EQ(emcy_class(0x9000), EmcyClass::external);
  EXPECT_EQ(emcy_class(0xF001), EmcyClass::additional_functions);
  EXPECT_EQ(emcy_class(0xFF10), EmcyClass::device_specific);
  EXPECT_EQ(emcy_class(0xA000), EmcyClass::other);
  EXPECT_EQ(emcy_class(0x0100), EmcyClass::other);
  EXPECT_EQ(lb::canopen::to_string(EmcyClass::device_specific), "device_specific");
  EXPECT_EQ(lb::canopen::to_string(EmcyClass::error_reset), "error_reset");
}

// An EMCY any bus member may have sent in the device's name (CAN is not authenticated): the
// device's own 1001h read afterwards says 00h, so nothing is active, and the note says which codes
// its register contradicts. A register that reports errors keeps the EMCY's code.
TEST(ActiveErrors, TheDevicesOwnRegisterReadAfterAnEmcyClearsWhatItContradicts) {
  ActiveErrors a;
  a.reset_by_boot_up();
  a.apply(emcy(0x5000, 0x01));
  ASSERT_EQ(codes(a), std::vector<std::uint16_t>{0x5000});
  EXPECT_EQ(a.checked_after_emcy(0x00), std::vector<std::uint16_t>{0x5000});
  EXPECT_TRUE(codes(a).empty());
  EXPECT_TRUE(a.known()) << "the device's own register says no error is active";
  EXPECT_EQ(a.error_register(), 0x00);
  EXPECT_EQ(a.note(), "EMCY 5000h cleared: the device's own error register 1001h read 00h after it (an error gone "
                      "by then, or an EMCY the device never sent: CAN frames are not authenticated)");
  // A real one later: listed, and the note about the earlier one goes.
  a.apply(emcy(0x4210, 0x09));
  EXPECT_EQ(codes(a), std::vector<std::uint16_t>{0x4210});
  EXPECT_TRUE(a.note().empty()) << a.note();
  EXPECT_TRUE(a.checked_after_emcy(0x09).empty());
  EXPECT_EQ(codes(a), std::vector<std::uint16_t>{0x4210}) << "the register reports an error: the EMCY stays";
  EXPECT_TRUE(a.known());
  EXPECT_EQ(a.error_register(), 0x09);
}
