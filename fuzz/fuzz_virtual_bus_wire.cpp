// The virtual bus's wire format (can/virtual_bus_wire), which any local process can write to a
// hub: any bytes are one valid classical frame or dropped, and a frame that is accepted encodes and
// decodes to itself.
#include <cstdint>
#include <cstring>
#include <span>

#include "can/virtual_bus_wire.hpp"

using namespace lb::can;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> message(data, size);
  (void)wire::is_welcome(message);
  const auto frame = wire::decode(message);
  if (!frame) return 0;
  if (frame->len > CanFrame::kMaxLen) __builtin_trap();
  if (frame->id > (frame->extended || frame->error ? 0x1FFF'FFFFU : 0x7FFU)) __builtin_trap();
  const wire::Msg m = wire::encode(*frame, 0);
  std::uint8_t bytes[sizeof m];
  std::memcpy(bytes, &m, sizeof m);
  const auto again = wire::decode(bytes);
  if (!again || again->id != frame->id || again->len != frame->len || again->extended != frame->extended ||
      again->rtr != frame->rtr || again->error != frame->error ||
      std::memcmp(again->data.data(), frame->data.data(), frame->len) != 0) {
    __builtin_trap();
  }
  return 0;
}
