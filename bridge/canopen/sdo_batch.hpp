#pragma once
// SDO requests to one node that run one after the other, for a procedure such as a device's boot:
// each waits for the previous, the first failure ends the batch (a configuration must not go on
// past a refused step), and a cancelled batch sends nothing more and reports nothing.

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "canopen/sdo_client.hpp"

namespace lb::canopen {

struct SdoRequest {
  enum class Kind { read, write };
  Kind kind = Kind::read;
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  DataType type = DataType::unsigned32;
  ObjectValue value{};  // write only
  // Read only: an object or sub-index the device lacks (06020000h, 06090011h) is an answer, not a
  // failure (CiA 301 optional entries).
  bool may_be_absent = false;

  static SdoRequest read(std::uint16_t index, std::uint8_t sub, DataType type, bool may_be_absent = false) {
    return {Kind::read, index, sub, type, {}, may_be_absent};
  }
  static SdoRequest write(std::uint16_t index, std::uint8_t sub, DataType type, ObjectValue value) {
    return {Kind::write, index, sub, type, std::move(value), false};
  }
};

struct SdoReply {
  std::optional<ObjectValue> value;  // a read that succeeded
  bool absent = false;               // a read of an optional entry the device lacks
  std::optional<SdoError> error;     // the failure that ended the batch (last reply only)
};

// done: one reply per request when all succeeded, else the replies up to the failed one, whose
// `error` is set. cancelled: asked before every request and before done; true stops silently.
void run_sdo_batch(SdoClient& sdo, std::uint8_t node, std::vector<SdoRequest> requests, std::function<bool()> cancelled,
                   std::function<void(std::vector<SdoReply>)> done);

// The value of an unsigned reply (0 when absent).
std::uint64_t unsigned_value(const SdoReply& reply);

}  // namespace lb::canopen
