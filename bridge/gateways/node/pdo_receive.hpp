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

// How PDO `pdo` and the device's other TPDOs are sent, as the PDO configuration in use says (the
// boot's, where it adopted the device's own): PdoBurst's per-cycle sample.
template <class Codec>
PdoBurst::Timing cycle_of(const Codec& codec, std::size_t pdo) {
  PdoBurst::Timing t;
  const auto& pdos = codec.pdos();
  for (std::size_t i = 0; i < pdos.size(); ++i) {
    const auto& def = *pdos[i].def;
    if (def.direction != profiles::PdoDirection::tx || !def.enabled) continue;
    if (def.transmission_type == 1) t.each_sync |= PdoBurst::bit(i);
    if (i == pdo) t.synchronous = def.synchronous();
  }
  return t;
}

// True when the frame is now in the codec's image; the caller then publishes it (burst.add, with
// cycle_of for its timing).
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
