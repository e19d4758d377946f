#pragma once
// What a client's SDO request (600h + node) asks of the device, by its command specifier (CiA 301:
// byte 0 bits 5..7): 0 download segment, 1 initiate download and 6 block download write to it;
// 2 initiate upload, 3 upload segment and 5 block upload read; 4 aborts.

#include "can/can_frame.hpp"

namespace lb::test {

inline bool sdo_download(const can::CanFrame& f) {
  if (f.len < 1) return false;
  const int ccs = f.data[0] >> 5;
  return ccs == 0 || ccs == 1 || ccs == 6;
}

}  // namespace lb::test
