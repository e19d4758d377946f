#include "app/line_bridge.hpp"

#include <spdlog/spdlog.h>

#include <stdexcept>

namespace lb::app {

Result<std::unique_ptr<LineBridge>> LineBridge::create(const profiles::LineConfig& config) {
  auto bridge = std::make_unique<LineBridge>(config);
  auto dds = ddsl::Participant::create({config.dds.domain, config.dds.localhost_only, "linebridge/" + config.line});
  if (!dds) return dds.error();
  bridge->dds_ = std::move(*dds);

  for (const auto& bus_cfg : config.buses) {
    const bool master = bus_cfg.role == profiles::BusRole::master;
    auto bus = can::open_bus(bus_cfg.interface, master ? can::BusAccess::read_write : can::BusAccess::listen_only);
    if (!bus) return make_error("bus " + bus_cfg.name + ": " + bus.error().message);
    BusRuntime rt{&bus_cfg, std::make_unique<canopen::BusLoop>(std::move(*bus)), nullptr, {}, {}};
    if (master) rt.sync = std::make_unique<canopen::SyncProducer>(*rt.loop, bus_cfg.sync_period);
    bridge->buses_.push_back(std::move(rt));
  }

  for (const auto& dev : config.devices) {
    auto& rt = *std::find_if(bridge->buses_.begin(), bridge->buses_.end(),
                             [&](const BusRuntime& b) { return b.config->name == dev.bus; });
    const bool master = rt.config->role == profiles::BusRole::master;
    rt.nodes.push_back(std::make_unique<canopen::RemoteNode>(*rt.loop, dev.node_id, dev.heartbeat_timeout, master));
    try {
      rt.gateways.push_back(gateways::make_gateway(gateways::DeviceContext{
          *rt.loop, *rt.nodes.back(), rt.sync.get(), *bridge->dds_, config.line, *rt.config, dev, *dev.resolved_profile}));
    } catch (const std::runtime_error& e) {
      return make_error(e.what());
    }
  }
  return bridge;
}

LineBridge::~LineBridge() {
  stop();
  // DDS first: no listener may call into a gateway that is being destroyed.
  dds_.reset();
}

void LineBridge::start() {
  for (auto& rt : buses_) {
    rt.loop->start();
    rt.loop->post([&rt] {
      for (auto& node : rt.nodes) node->start();
      if (rt.sync) rt.sync->start();
    });
    spdlog::info("bus {} on {} started as {}", rt.config->name, rt.config->interface, profiles::to_string(rt.config->role));
  }
}

void LineBridge::stop() {
  for (auto& rt : buses_) rt.loop->stop();
}

}  // namespace lb::app
