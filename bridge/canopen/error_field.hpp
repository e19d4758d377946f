#pragma once
// What the master reads about a device's errors after its boot (CiA 301): the error register 1001h
// (0: no error active), which reconciles the active-error list kept from the EMCYs
// (ActiveErrors), and the pre-defined error field 1003h, which is the device's error HISTORY:
// sub 0 the number of errors recorded, sub 1 the newest, older ones at higher sub-indices; every
// EMCY the device sent is there, error resets (0000h) included, and errors long cleared stay.
// 1003h therefore never says which errors are active now: it is read and published as history.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "canopen/emcy.hpp"
#include "canopen/sdo_client.hpp"

namespace lb::canopen {

// 1003h as read.
struct ErrorHistory {
  // The newest entries read at most: one SDO transfer each, after every boot (the DDS bound).
  static constexpr std::size_t kMaxEntries = 16;

  bool read = false;                   // false: see remark
  std::uint8_t count = 0;              // sub 0: how many the device has recorded (may exceed entries)
  std::vector<std::uint32_t> entries;  // sub 1..: newest first; bits 0..15 the EMCY error code
  std::string remark;                  // why not read: the device has no 1003h, the read failed
};

struct ErrorFieldReading {
  std::uint8_t error_register = 0;
  std::optional<SdoError> error;  // 1001h could not be read
  ErrorHistory history;
};

// Loop thread or any; done runs on the loop thread. cancelled as run_sdo_batch's.
void read_error_field(SdoClient& sdo, std::uint8_t node, const std::function<bool()>& cancelled,
                      std::function<void(ErrorFieldReading)> done);

// The register read applied to the active list (ActiveErrors::reconcile); the history plays no
// part. A failed read changes nothing a boot-up or the EMCYs established; an uncertain list says
// it could not be read.
void apply(ActiveErrors& errors, const ErrorFieldReading& reading);

}  // namespace lb::canopen
