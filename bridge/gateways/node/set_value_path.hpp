#pragma once
// The path of a set value from its DDS listener to the device's RPDO image, the same for every
// gateway whose device takes set values. On the DDS thread: refused on a monitor bus, or when
// validate() refuses (it reads only the immutable profile, so it needs no lock). On the bus loop:
// refused while the device is offline, else apply(raw) and answered as accepted. Every refusal is
// answered; the log gets them at a bounded rate (log, one per gateway).

#include <spdlog/spdlog.h>

#include <cstdint>
#include <string>
#include <string_view>

#include "base/shared_log_rate.hpp"
#include "gateways/node/device_context.hpp"

namespace lb::gateways {

// The answer to a request while the bridge yields to another master on the device's bus.
inline std::string another_master(const DeviceContext& ctx, std::string_view what) {
  return "another master's SYNC runs on bus " + ctx.bus.name +
         ": the bridge transmits nothing there until it is silent (diagnostics: "
         "yielding_to_other_master): " +
         std::string(what);
}

// validate: () -> Result<Raw>; apply: (const Raw&) on the loop thread, the codec's image only;
// applied: () on the loop thread once a set value is taken (send, publish, log);
// reply: (request_id, accepted, reason) from either thread. pdos: the device's PdoWiring.
// A device that has not passed its boot (or whose state the bridge lost) but is heard takes a set
// value that enables nothing (program off, extruder stopped, a speed): a stop is never refused
// while the device is heard. One that would switch it on is refused, and the image left as it was.
template <class Pdos, class Validate, class Apply, class Applied, class Reply>
void take_set_value(const DeviceContext& ctx, Pdos& pdos, SharedLogRate& log, std::uint64_t id, Validate validate,
                    Apply apply, Applied applied, Reply reply) {
  if (!ctx.is_master()) {
    return reply(id, false, "bus " + ctx.bus.name + " is in the monitor role: the bridge never transmits there");
  }
  auto raw = validate();
  if (!raw) {
    if (auto more = log.allow())
      spdlog::warn("{}: set value {} refused: {}{}", ctx.device.name, id, raw.error().message, *more);
    return reply(id, false, raw.error().message);
  }
  const bool posted = ctx.loop.try_post([&ctx, &pdos, &log, id, r = *raw, apply, applied, reply] {
    if (ctx.loop.transmission_held()) {
      if (auto more = log.allow())
        spdlog::warn("{}: set value {} refused: another master runs bus {}{}", ctx.device.name, id, ctx.bus.name,
                     *more);
      return reply(id, false, another_master(ctx, "set value not applied"));
    }
    if (!ctx.node.online()) {
      if (auto more = log.allow())
        spdlog::warn("{}: set value {} refused: device offline{}", ctx.device.name, id, *more);
      return reply(id, false, ctx.device.name + " is offline (no heartbeat): set value not applied");
    }
    if (ctx.node.configured()) {
      apply(r);
      applied();
      return reply(id, true, "");
    }
    const auto before = pdos.image();
    apply(r);
    if (pdos.carries_enabling()) {
      pdos.restore_image(before);
      if (auto more = log.allow()) {
        spdlog::warn("{}: set value {} refused: the device has not passed its boot and it would enable it{}",
                     ctx.device.name, id, *more);
      }
      return reply(id, false,
                   ctx.device.name + " has not passed its boot (see its info topic): a set value that switches it on "
                                     "is refused (one that enables nothing is taken)");
    }
    if (pdos.takes_a_safe_image()) pdos.safe_image_asked();
    applied();
    reply(id, true,
          pdos.takes_a_safe_image() ? ""
                                    : ctx.device.name + " has not passed its boot: taken, sent once it is started");
  });
  if (!posted) reply(id, false, ctx.loop_busy("set value"));
}

}  // namespace lb::gateways
