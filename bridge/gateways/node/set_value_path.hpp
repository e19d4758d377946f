#pragma once
// The path of a set value from its DDS listener to the device's output, the same for every gateway
// whose device takes set values. On the DDS thread: refused on a monitor bus, or when validate()
// refuses (it reads only the immutable profile, so it needs no lock). On the bus loop: the device's
// DeviceOutput takes it or refuses it (a stop goes out while the device is heard and is answered
// once on the bus; device_output.hpp). Every refusal is answered; the log gets them at a bounded
// rate (log, one per gateway).

#include <spdlog/spdlog.h>

#include <cstdint>
#include <string>

#include "base/shared_log_rate.hpp"
#include "gateways/node/device_context.hpp"

namespace lb::gateways {

// validate: () -> Result<Raw>; apply: (const Raw&) on the loop thread, the codec's image only (it
// may run more than once: DeviceOutput tries a change on copies first); applied: () on the loop
// thread once a set value is taken (publish, log); reply: (request_id, accepted, reason) from
// either thread. output: the device's DeviceOutput.
template <class Output, class Validate, class Apply, class Applied, class Reply>
void take_set_value(const DeviceContext& ctx, Output& output, SharedLogRate& log, std::uint64_t id, Validate validate,
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
  const bool posted = ctx.loop.try_post([&ctx, &output, &log, id, r = *raw, apply, applied, reply] {
    output.take([&apply, &r] { apply(r); },
                [&ctx, &log, id, applied, reply](bool accepted, const std::string& reason) {
                  if (accepted) {
                    applied();
                  } else if (auto more = log.allow()) {
                    spdlog::warn("{}: set value {} refused: {}{}", ctx.device.name, id, reason, *more);
                  }
                  reply(id, accepted, reason);
                });
  });
  if (!posted) reply(id, false, ctx.loop_busy("set value"));
}

}  // namespace lb::gateways
