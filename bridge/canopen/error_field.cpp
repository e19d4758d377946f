#include "canopen/error_field.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "canopen/sdo_batch.hpp"

namespace lb::canopen {

namespace {

constexpr std::uint16_t kErrorRegister = 0x1001, kErrorField = 0x1003;

}  // namespace

void read_error_field(SdoClient& sdo, std::uint8_t node, const std::function<bool()>& cancelled,
                      std::function<void(ErrorFieldReading)> done) {
  std::vector<SdoRequest> first{SdoRequest::read(kErrorRegister, 0, DataType::unsigned8),
                                SdoRequest::read(kErrorField, 0, DataType::unsigned8, true)};
  run_sdo_batch(sdo, node, std::move(first), cancelled,
                [&sdo, node, cancelled, done = std::move(done)](std::vector<SdoReply> replies) {
                  ErrorFieldReading reading;
                  if (replies.size() < 2) {  // 1001h failed: the batch ended there
                    reading.error = replies.back().error;
                    reading.history.remark = "not read: 1001h could not be read";
                    return done(std::move(reading));
                  }
                  reading.error_register = static_cast<std::uint8_t>(unsigned_value(replies[0]));
                  if (replies[1].error) {
                    reading.history.remark = "1003h sub 0 could not be read: " + replies[1].error->message;
                    return done(std::move(reading));
                  }
                  if (replies[1].absent) {
                    reading.history.remark = "the device has no 1003h (pre-defined error field)";
                    return done(std::move(reading));
                  }
                  // Read whatever the register says: the history is worth publishing even when no
                  // error is active (it is how a device tells what happened before).
                  reading.history.count = static_cast<std::uint8_t>(unsigned_value(replies[1]));
                  const auto n = std::min<std::size_t>(reading.history.count, ErrorHistory::kMaxEntries);
                  std::vector<SdoRequest> entries;
                  for (std::size_t sub = 1; sub <= n; ++sub) {
                    entries.push_back(
                        SdoRequest::read(kErrorField, static_cast<std::uint8_t>(sub), DataType::unsigned32, true));
                  }
                  if (entries.empty()) {
                    reading.history.read = true;
                    return done(std::move(reading));
                  }
                  run_sdo_batch(sdo, node, std::move(entries), cancelled,
                                [reading = std::move(reading), done](std::vector<SdoReply> entries_read) mutable {
                                  if (entries_read.back().error) {
                                    reading.history.remark = "1003h could not be read: " +
                                                             entries_read.back().error->message;
                                    return done(std::move(reading));
                                  }
                                  // In sub-index order, which is newest first.
                                  for (const auto& r : entries_read) {
                                    if (r.absent) break;  // fewer than the count said
                                    reading.history.entries.push_back(static_cast<std::uint32_t>(unsigned_value(r)));
                                  }
                                  reading.history.read = true;
                                  done(std::move(reading));
                                });
                });
}

void apply(ActiveErrors& errors, const ErrorFieldReading& reading) {
  if (reading.error) {
    // The EMCYs since a boot-up stay true without the register. A list not known for want of a
    // boot-up says the read failed too; one made uncertain by an EMCY keeps that reason.
    if (!errors.known() && errors.note().starts_with("not known yet")) {
      errors.mark_uncertain("not known: no boot-up seen and the error register 1001h could not be read: " +
                            reading.error->message);
    }
    return;
  }
  errors.reconcile(reading.error_register);
}

}  // namespace lb::canopen
