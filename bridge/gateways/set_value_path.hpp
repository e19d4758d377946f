#pragma once
// The path of a set value from its DDS listener to the device's RPDO image, the same for every
// gateway whose device takes set values. On the DDS thread: refused on a monitor bus, or when
// validate() refuses (it reads only the immutable profile, so it needs no lock). On the bus loop:
// refused while the device is offline, else apply(raw) and answered as accepted. Every refusal is
// answered; the log gets them at a bounded rate (log, one per gateway).

#include <spdlog/spdlog.h>

#include <cstdint>
#include <string>

#include "base/shared_log_rate.hpp"
#include "gateways/device_context.hpp"

namespace lb::gateways {

// validate: () -> Result<Raw>; apply: (const Raw&) on the loop thread;
// reply: (request_id, accepted, reason) from either thread.
template <class Validate, class Apply, class Reply>
void take_set_value(const DeviceContext& ctx, SharedLogRate& log, std::uint64_t id, Validate validate, Apply apply,
                    Reply reply) {
  if (!ctx.is_master()) {
    return reply(id, false, "bus " + ctx.bus.name + " is in the monitor role: the bridge never transmits there");
  }
  auto raw = validate();
  if (!raw) {
    if (auto more = log.allow()) spdlog::warn("{}: set value {} refused: {}{}", ctx.device.name, id, raw.error().message, *more);
    return reply(id, false, raw.error().message);
  }
  const bool posted = ctx.loop.try_post([&ctx, &log, id, r = *raw, apply, reply] {
    if (!ctx.node.online()) {
      if (auto more = log.allow()) spdlog::warn("{}: set value {} refused: device offline{}", ctx.device.name, id, *more);
      return reply(id, false, ctx.device.name + " is offline (no heartbeat): set value not applied");
    }
    if (!ctx.node.configured()) {
      if (auto more = log.allow()) {
        spdlog::warn("{}: set value {} refused: the device has not passed its boot{}", ctx.device.name, id, *more);
      }
      return reply(id, false, ctx.device.name + " has not passed its boot (see its info topic): set value not applied");
    }
    apply(r);
    reply(id, true, "");
  });
  if (!posted) reply(id, false, ctx.loop_busy("set value"));
}

}  // namespace lb::gateways
