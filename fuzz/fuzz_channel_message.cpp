// The channel between a line's bus process and its DDS process (link/channel_message), whose
// datagrams each side reads from the other: any bytes are one message of this version or refused
// with a reason, and a message that is accepted encodes to exactly the bytes it came from (no
// field is read past its datagram, and nothing is silently ignored).
#include <cstdint>
#include <cstring>
#include <span>

#include "link/channel_message.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> datagram(data, size);
  auto message = lb::link::decode(datagram);
  if (!message) {
    if (message.error().message.empty()) __builtin_trap();
    return 0;
  }
  const auto again = lb::link::encode(*message);
  if (again.size() != size || std::memcmp(again.data(), data, size) != 0) __builtin_trap();
  return 0;
}
