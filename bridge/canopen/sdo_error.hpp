#pragma once
// Why an SDO transfer failed: the CiA 301 abort code, so callers can branch on the cause, and a
// message a person can act on (node, object, code, meaning and who gave up).

#include <fmt/format.h>

#include <cstdint>
#include <string>
#include <string_view>

#include "canopen/sdo_abort.hpp"

namespace lb::canopen {

struct SdoError {
  std::uint32_t abort_code = sdo_abort::general_error;
  std::string message;
};

// server: the server sent the abort. client: this client aborted the transfer and told the server
// so (timeout, bad toggle, bad response). local: nothing was aborted on the bus, the request failed
// here (bus send failed, client destroyed, a value that cannot be encoded); the code then is the
// closest standard one, usually general error.
enum class SdoErrorOrigin { server, client, local };

inline SdoError make_sdo_error(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t code,
                               SdoErrorOrigin origin, std::string_view detail = {}) {
  std::string_view who = "aborted by the server";
  if (origin == SdoErrorOrigin::client) who = "aborted by the client";
  if (origin == SdoErrorOrigin::local) who = "failed locally (no abort from the server)";
  std::string message = fmt::format("SDO node {} {:04X}h:{:02X}: {}: {:08X}h {}", node, index, sub, who, code,
                                    sdo_abort_meaning(code));
  if (!detail.empty()) message += fmt::format(" ({})", detail);
  return SdoError{code, std::move(message)};
}

}  // namespace lb::canopen
