#pragma once
// When a service call's SDO request may go to its device. A request that cannot succeed is refused
// at once with the reason instead of waiting in the device's queue (and running after its caller
// gave up): the device is offline (no heartbeat), or stopped (CiA 301: a stopped device answers
// no SDO). A device in pre-operational, whose boot failed for instance, answers SDO and is served:
// that is how an integrator finds out why. At most kServiceSdoLimit service requests wait per
// device; one more is refused at once (SdoClient::Limit). The bridge's own requests (boot, polls)
// are not counted.

#include <functional>
#include <string>

#include "canopen/sdo_client.hpp"
#include "gateways/node/device_context.hpp"

namespace lb::gateways {

inline constexpr canopen::SdoClient::Limit kServiceSdoLimit{8};

// Loop thread: why an SDO request to the device cannot succeed now; empty when it can.
// answered_boot: the device has no heartbeat but answered its last boot's SDO requests (the boot
// failed later, e.g. on a mapping): it is asked, since that is how an integrator finds out why.
// stop: the request stops a machine (the feeder's 600Eh stop modes): it goes whenever the device
// is heard (RemoteNode::heard), whatever its heartbeat supervision believes.
inline std::string sdo_refusal(const DeviceContext& ctx, bool answered_boot = false, bool stop = false) {
  if (stop && !ctx.node.heard_now()) {
    return ctx.device.name + " is not heard (no frame of its own within its heartbeat timeout): the stop cannot reach "
                             "it; SDO request not sent";
  }
  if (!stop && !ctx.node.online() && !answered_boot)
    return ctx.device.name + " is offline (no heartbeat): SDO request not sent";
  // A stop is refused as stopped only when everything agrees: the bridge itself may just have
  // started the device (an operator's NMT start) and its first operational heartbeat may be under
  // way; a stop sent to a stopped device costs a timeout, one refused to a running one a machine.
  const bool stopped = stop ? ctx.node.state() == canopen::NmtState::stopped &&
                                  ctx.node.reported_state() == canopen::NmtState::stopped &&
                                  ctx.node.commanded_state() == canopen::NmtState::stopped
                            : ctx.node.state() == canopen::NmtState::stopped;
  if (stopped) {
    return ctx.device.name + " is stopped (NMT): a stopped device answers no SDO (CiA 301); SDO request not sent";
  }
  return {};
}

// Any thread: runs send() on the loop thread when the device can answer SDO, else refuse(why) there.
template <class Send, class Refuse>
void when_sdo_possible(const DeviceContext& ctx, Send send, Refuse refuse, std::function<bool()> answered_boot = {},
                       bool stop = false) {
  // refuse is needed on both paths: the copy answers when the loop has no room for the request.
  auto busy = refuse;
  const bool posted = ctx.loop.try_post([&ctx, send = std::move(send), refuse = std::move(refuse),
                                         answered_boot = std::move(answered_boot), stop]() mutable {
    if (auto why = sdo_refusal(ctx, answered_boot && answered_boot(), stop); !why.empty()) return refuse(why);
    send();
  });
  if (!posted) busy(ctx.loop_busy("SDO request"));
}

}  // namespace lb::gateways
