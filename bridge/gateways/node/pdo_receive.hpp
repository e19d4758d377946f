#pragma once
// A PDO received from the bus into a device's process image, the same for every gateway: the
// burst publishes first what waits if this PDO's previous values are among it (so none is
// overwritten unpublished), then the frame is decoded, or counted and reported when it cannot be
// (a short PDO would otherwise publish garbage). Loop thread.

#include <spdlog/spdlog.h>

#include <cstddef>

#include "can/can_frame.hpp"
#include "gateways/node/device_context.hpp"
#include "gateways/node/pdo_burst.hpp"

namespace lb::gateways {

// True when the frame is now in the codec's image; the caller then publishes it (burst.add).
template <class Codec>
bool receive_pdo(const DeviceContext& ctx, Codec& codec, PdoBurst& burst, std::size_t pdo, const can::CanFrame& frame) {
  auto& stats = ctx.node.stats();
  burst.admit(pdo);
  if (auto r = codec.receive(pdo, frame.payload()); !r) {
    if (stats.pdo_length_errors++ % 1000 == 0) {
      spdlog::warn("{}: {} ({:03X}h) not decoded: {} ({} so far)", ctx.device.name, codec.pdos()[pdo].def->name,
                   frame.id, r.error().message, stats.pdo_length_errors);
    }
    return false;
  }
  ++stats.pdos_received;
  return true;
}

}  // namespace lb::gateways
