#include "canopen/error_field.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <memory>

#include "canopen/sdo_batch.hpp"

namespace lb::canopen {

namespace {

constexpr std::uint16_t kErrorRegister = 0x1001, kErrorField = 0x1003;

}  // namespace

void read_error_field(SdoClient& sdo, std::uint8_t node, std::function<bool()> cancelled,
                      std::function<void(ErrorFieldReading)> done) {
  std::vector<SdoRequest> first{SdoRequest::read(kErrorRegister, 0, DataType::unsigned8),
                                SdoRequest::read(kErrorField, 0, DataType::unsigned8, true)};
  run_sdo_batch(sdo, node, std::move(first), cancelled,
                [&sdo, node, cancelled, done = std::move(done)](std::vector<SdoReply> replies) {
                  ErrorFieldReading reading;
                  if (replies.back().error) {
                    reading.error = replies.back().error;
                    return done(std::move(reading));
                  }
                  reading.error_register = static_cast<std::uint8_t>(unsigned_value(replies[0]));
                  // Register 0: no error is active, whatever history 1003h keeps (CiA 301).
                  if (reading.error_register == 0 || replies[1].absent) return done(std::move(reading));
                  // Only the active list's size: the newest ActiveErrors::kMax entries.
                  const auto count = std::min<std::uint64_t>(unsigned_value(replies[1]), ActiveErrors::kMax);
                  std::vector<SdoRequest> entries;
                  for (std::uint64_t sub = 1; sub <= count; ++sub) {
                    entries.push_back(SdoRequest::read(kErrorField, static_cast<std::uint8_t>(sub), DataType::unsigned32, true));
                  }
                  if (entries.empty()) {
                    reading.codes.emplace();
                    return done(std::move(reading));
                  }
                  run_sdo_batch(sdo, node, std::move(entries), cancelled,
                                [reading, done](std::vector<SdoReply> entries_read) mutable {
                                  if (entries_read.back().error) {
                                    reading.error = entries_read.back().error;
                                    return done(std::move(reading));
                                  }
                                  std::vector<std::uint16_t> codes;
                                  for (const auto& r : entries_read) {
                                    if (!r.absent) codes.push_back(static_cast<std::uint16_t>(unsigned_value(r) & 0xFFFF));
                                  }
                                  std::reverse(codes.begin(), codes.end());  // 1003h: sub 1 is the newest
                                  reading.codes = std::move(codes);
                                  done(std::move(reading));
                                });
                });
}

void apply(ActiveErrors& errors, const ErrorFieldReading& reading) {
  if (reading.error) return errors.mark_uncertain("the device's errors could not be read: " + reading.error->message);
  if (reading.error_register == 0) return errors.replace({}, 0, "");
  if (reading.codes) {
    return errors.replace(*reading.codes, reading.error_register,
                          fmt::format("as the device lists them in 1003h (error register {:02X}h)", reading.error_register));
  }
  errors.mark_uncertain(fmt::format("error register 1001h = {:02X}h and the device has no 1003h (pre-defined error "
                                    "field): which errors remain is unknown",
                                    reading.error_register),
                        reading.error_register);
}

}  // namespace lb::canopen
