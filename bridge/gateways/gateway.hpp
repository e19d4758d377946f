#pragma once
// A device gateway: lives as long as the bridge runs; all its work is driven by its bus loop and
// its DDS subscriptions, so the only thing its owner does with it is keep it alive.

#include <memory>

#include "gateways/device_context.hpp"

namespace lb::gateways {

class Gateway {
 public:
  virtual ~Gateway() = default;
};

// The gateway for the device type its profile names ("saw", ...); throws at start-up for a device
// type no gateway serves yet.
std::unique_ptr<Gateway> make_gateway(DeviceContext context);

}  // namespace lb::gateways
