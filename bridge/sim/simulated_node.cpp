#include "sim/simulated_node.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "sim/device_dictionary.hpp"

namespace lb::sim {

using canopen::NmtState;
using profiles::PdoDirection;

namespace {
constexpr double kMaxStep = 0.1;  // s: a stalled loop must not make the simulation jump
}  // namespace

SimulatedNode::SimulatedNode(canopen::BusLoop& loop, const profiles::DeviceConfig& device, const profiles::Profile& profile,
                             Application application)
    : loop_(loop),
      device_(device),
      profile_(profile),
      app_(std::move(application)),
      nmt_(loop, device.node_id, device.simulation.heartbeat_period, [this] { reset(); }),
      sdo_(loop, device.node_id, make_device_dictionary(device, profile)) {
  // Every object gets its slot before any PDO is bound: a binding skips objects not in the image.
  for (const auto& o : profile_.objects) {
    if (o.type != canopen::DataType::visible_string && o.type != canopen::DataType::octet_string) {
      (void)image_.slot(o.index, o.sub);
    }
  }
  tpdo_bindings_.reserve(device_.pdos.size());  // the transmitters keep pointers into it
  for (const auto& pdo : device_.pdos) {
    auto mapping = canopen::PdoMapping::create(pdo.mapping);
    if (!mapping) throw std::runtime_error(device_.name + " " + pdo.name + ": " + mapping.error().message);
    if (!pdo.enabled) continue;
    canopen::PdoBinding binding(std::move(*mapping), image_);
    if (pdo.direction == PdoDirection::tx) {
      const auto* b = &tpdo_bindings_.emplace_back(std::move(binding));
      tpdos_.push_back(std::make_unique<canopen::PdoTransmitter>(
          loop_, canopen::PdoTransmitter::Settings{pdo.can_id, pdo.extended, pdo.transmission_type, pdo.inhibit, pdo.event_timer},
          [this, b](can::CanFrame& f) { f.len = b->pack_from(image_, std::span<std::uint8_t, 8>(f.data)); },
          [this] { return nmt_.state() == NmtState::operational; }));
    } else {
      rpdos_.push_back({&pdo, std::move(binding), std::nullopt});
    }
  }
  for (std::size_t i = 0; i < rpdos_.size(); ++i) {
    const auto handler = [this, i](const can::CanFrame& f) {
      if (nmt_.state() != NmtState::operational) return;
      Rpdo& r = rpdos_[i];
      if (r.def->synchronous()) r.pending = f;
      else apply_rpdo(r, f);  // event-driven: takes effect at once
    };
    if (rpdos_[i].def->extended) loop_.on_extended_frame(rpdos_[i].def->can_id, handler);
    else loop_.on_frame(rpdos_[i].def->can_id, handler);
  }
  loop_.on_frame(canopen::cob::sync, [this](const can::CanFrame&) { on_sync(); });
  link_dictionary();
}

std::size_t SimulatedNode::slot(std::string_view object) const {
  const auto* def = profile_.object(object);
  const std::size_t s = def != nullptr ? image_.find(def->index, def->sub) : canopen::ProcessImage::npos;
  if (s == canopen::ProcessImage::npos) throw std::runtime_error(device_.name + ": profile has no object " + std::string(object));
  return s;
}

std::optional<unsigned> SimulatedNode::bit(std::string_view set, std::string_view name) const {
  const auto* s = profile_.bitset(set);
  return s != nullptr ? s->bit(name) : std::nullopt;
}

void SimulatedNode::reset() {
  for (const auto& o : profile_.objects) {
    const std::size_t s = image_.find(o.index, o.sub);
    if (s != canopen::ProcessImage::npos) image_.set(s, 0);
  }
  // ARRAY objects: sub 0 tells how many elements the device has (all the profile allows).
  for (const auto& o : profile_.objects) {
    if (o.sub == 0) continue;
    const std::size_t count = image_.find(o.index, 0);
    if (count != canopen::ProcessImage::npos) image_.set(count, std::max<std::uint64_t>(image_.get(count), o.sub));
  }
  last_sync_.reset();
  if (app_.reset) app_.reset();
  publish_to_dictionary();
}

void SimulatedNode::link_dictionary() {
  auto& od = sdo_.dictionary();
  for (const auto& o : profile_.objects) {
    const std::size_t s = image_.find(o.index, o.sub);
    if (s == canopen::ProcessImage::npos || !o.writable()) continue;
    (void)od.set_on_write(o.index, o.sub, [this, s](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
      std::uint64_t raw = 0;
      for (std::size_t i = 0; i < v.size() && i < 8; ++i) raw |= std::uint64_t{v[i]} << (8 * i);
      image_.set(s, raw);
      return std::nullopt;
    });
  }
  (void)od.set_on_write(0x1017, 0, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    nmt_.set_heartbeat_period(std::chrono::milliseconds(v[0] | v[1] << 8));
    return std::nullopt;
  });
}

void SimulatedNode::publish_to_dictionary() {
  auto& od = sdo_.dictionary();
  for (const auto& o : profile_.objects) {
    const std::size_t s = image_.find(o.index, o.sub);
    if (s == canopen::ProcessImage::npos) continue;
    const std::size_t n = canopen::bit_size(o.type) / 8;
    std::vector<std::uint8_t> bytes(n);
    for (std::size_t i = 0; i < n; ++i) bytes[i] = static_cast<std::uint8_t>(image_.get(s) >> (8 * i));
    (void)od.set(o.index, o.sub, std::move(bytes));
  }
}

void SimulatedNode::on_sync() {
  const auto now = std::chrono::steady_clock::now();
  const double dt = last_sync_ ? std::min(std::chrono::duration<double>(now - *last_sync_).count(), kMaxStep) : 0.0;
  last_sync_ = now;
  if (nmt_.state() != NmtState::operational) return;
  for (auto& r : rpdos_) {
    if (!r.pending) continue;
    apply_rpdo(r, *r.pending);
    r.pending.reset();
  }
  if (app_.step) app_.step(dt);
  publish_to_dictionary();
  for (auto& t : tpdos_) {
    t->on_sync();
    t->on_data();
  }
}

void SimulatedNode::apply_rpdo(Rpdo& rpdo, const can::CanFrame& frame) {
  if (!rpdo.binding.unpack_into(frame.payload(), image_)) {
    if (short_rpdos_++ % 100 == 0) spdlog::warn("sim {}: {} shorter than its mapping ignored", device_.name, rpdo.def->name);
  }
}

}  // namespace lb::sim
