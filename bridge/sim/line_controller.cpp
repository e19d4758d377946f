#include "sim/line_controller.hpp"

#include <spdlog/spdlog.h>

#include <stdexcept>

#include "canopen/nmt.hpp"

namespace lb::sim {

LineController::LineController(canopen::BusLoop& loop, const profiles::BusConfig& bus,
                               const std::vector<const profiles::DeviceConfig*>& devices)
    : loop_(loop), sync_(loop, bus.sync_period) {
  for (const auto* dev : devices) {
    const auto& profile = *dev->resolved_profile;
    auto image = std::make_unique<canopen::ProcessImage>();
    for (const auto& [name, raw] : dev->simulation.controller_values) {
      const auto* obj = profile.object(name);
      image->set(image->slot(obj->index, obj->sub), raw);
    }
    for (const auto& pdo : dev->pdos) {
      if (pdo.direction != profiles::PdoDirection::rx || !pdo.enabled) continue;
      for (const auto& e : pdo.mapping) {
        if (!e.is_dummy()) image->slot(e.index, e.sub);
      }
      auto mapping = canopen::PdoMapping::create(pdo.mapping);
      if (!mapping) throw std::runtime_error(dev->name + " " + pdo.name + ": " + mapping.error().message);
      rpdos_.push_back({pdo.can_id, pdo.extended, canopen::PdoBinding(std::move(*mapping), *image), image.get()});
    }
    images_.push_back(std::move(image));
    nodes_.push_back(dev->node_id);
    // A device that (re)boots is started again, as a line controller does.
    loop_.on_frame(canopen::cob::heartbeat_base + dev->node_id, [this, id = dev->node_id](const can::CanFrame& f) {
      if (f.len >= 1 && canopen::nmt_state_from_byte(f.data[0]) == canopen::NmtState::boot_up) {
        (void)loop_.send(canopen::make_nmt_command(canopen::NmtCommand::start, id));
      }
    });
  }
  sync_.on_sync([this] {
    for (const auto& r : rpdos_) {
      can::CanFrame f;
      f.id = r.can_id;
      f.extended = r.extended;
      f.len = r.binding.pack_from(*r.image, std::span<std::uint8_t, 8>(f.data));
      (void)loop_.send(f);
    }
  });
}

void LineController::start() {
  for (auto id : nodes_) (void)loop_.send(canopen::make_nmt_command(canopen::NmtCommand::start, id));
  sync_.start();
  spdlog::info("sim: line controller on {}: SYNC, NMT start and RPDOs for {} device(s)", loop_.bus().uri(),
               nodes_.size());
}

}  // namespace lb::sim
