#pragma once
// A device's active errors read from the device itself (master role): its error register 1001h
// and, when that is not 0, its pre-defined error field 1003h (sub 0 the count, sub 1 the newest;
// bits 0..15 of each entry the EMCY error code). This is what makes the active-error list true
// again after an EMCY 0000h that left errors, and what a master knows about errors raised before it
// started.

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "canopen/emcy.hpp"
#include "canopen/sdo_client.hpp"

namespace lb::canopen {

struct ErrorFieldReading {
  std::uint8_t error_register = 0;
  std::optional<std::vector<std::uint16_t>> codes;  // oldest first; nullopt: the device has no 1003h
  std::optional<SdoError> error;                    // 1001h or 1003h could not be read
};

// Loop thread or any; done runs on the loop thread. cancelled as run_sdo_batch's.
void read_error_field(SdoClient& sdo, std::uint8_t node, std::function<bool()> cancelled,
                      std::function<void(ErrorFieldReading)> done);

// The reading applied to the list: replaced by the device's own, or flagged as uncertain with the
// reason (the device has no 1003h while its register says errors remain, or the read failed).
void apply(ActiveErrors& errors, const ErrorFieldReading& reading);

}  // namespace lb::canopen
