#pragma once
// A device gateway: lives as long as the bridge runs; all its work is driven by its bus loop (as
// one of its node's drivers: canopen/node_driver.hpp) and its DDS subscriptions, so the only thing
// its owner does with it is keep it alive.

#include <memory>

#include "canopen/node_driver.hpp"
#include "gateways/node/device_context.hpp"

namespace lb::gateways {

class CommandService;

class Gateway : public canopen::NodeDriver {
 public:
  Gateway() = default;
  Gateway(const Gateway&) = delete;
  Gateway& operator=(const Gateway&) = delete;
  virtual ~Gateway() = default;

  // The device's momentary commands for the line-wide `command` service, or null for a device
  // type that has none (a feeder's commands are its own typed services).
  virtual const CommandService* commands() const { return nullptr; }
};

// The gateway for the device type its profile names, by its registry entry's behaviour
// (make_gateway.cpp); throws at start-up for a device type the registry lacks.
std::unique_ptr<Gateway> make_gateway(DeviceContext context);

}  // namespace lb::gateways
