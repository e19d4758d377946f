#pragma once
// A device's PDOs on its bus loop, the same for every gateway: the TPDOs it sends (and, on a
// monitor bus, the RPDOs a line controller sends it) handed to the gateway by PDO index; the
// RPDOs the bridge sends from the codec's image by their transmission type, only while the device
// may take them (master role); and the PDOs the device's boot left in use taken over before the
// device is started (pdo_config: adopt, or a PDO the device does not have).
// Codec: pdos() (each with `def`, the DevicePdo it decodes by, and `binding`), pack(i, out),
// use_pdo(i, DevicePdo).

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>
#include <cstddef>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/pdo_transmitter.hpp"
#include "gateways/device_context.hpp"
#include "gateways/pdo_specs.hpp"

namespace lb::gateways {

template <class Codec>
class PdoWiring {
 public:
  using Receive = std::function<void(std::size_t pdo, const can::CanFrame& frame)>;
  using Gate = std::function<bool()>;
  struct Rpdo {
    std::size_t pdo;  // index in the codec
    std::unique_ptr<canopen::PdoTransmitter> transmitter;
    bool valid_on_device = true;
  };

  // Before the loop starts. gate: the gateway's own condition for sending (besides the device's).
  PdoWiring(const DeviceContext& ctx, Codec& codec, Receive receive, Gate gate = {})
      : ctx_(ctx), codec_(codec), gate_(std::move(gate)) {
    for (std::size_t i = 0; i < codec_.pdos().size(); ++i) {
      const auto& pdo = *codec_.pdos()[i].def;
      if (!pdo.enabled) continue;  // COB-ID bit 31: this PDO does not exist on the bus
      if (pdo.direction == profiles::PdoDirection::tx || !ctx_.is_master()) {
        const auto handler = [receive, i](const can::CanFrame& f) { receive(i, f); };
        if (pdo.extended) ctx_.loop.on_extended_frame(pdo.can_id, handler);
        else ctx_.loop.on_frame(pdo.can_id, handler);
        continue;
      }
      const std::size_t k = rpdos_.size();
      using Transmitter = canopen::PdoTransmitter;
      rpdos_.push_back(
          {i, std::make_unique<Transmitter>(
                  ctx_.loop, settings(pdo),
                  Transmitter::Hooks{
                      .pack = [this, i](can::CanFrame& f) { f.len = codec_.pack(i, std::span<std::uint8_t, 8>(f.data)); },
                      .may_send = [this, k] { return may_send(k); },
                      .before_send = [this, i] { notify(i, [](const RpdoObserver& o) { o.before_send(); }); },
                      .sent =
                          [this, i](const can::CanFrame&, std::chrono::steady_clock::time_point at) {
                            ++ctx_.node.stats().pdos_sent;
                            notify(i, [at](const RpdoObserver& o) { o.sent(at); });
                          },
                      .not_sent =
                          [this, i, k](Transmitter::Refusal why) {
                            if (observed(i)) {
                              const auto text = why == Transmitter::Refusal::bus
                                                    ? std::string("the bus refused the frame (diagnostics: tx_dropped)")
                                                    : why_not(k);
                              notify(i, [&text](const RpdoObserver& o) { o.not_sent(text); });
                            }
                          }})});
    }
    if (ctx_.is_master()) ctx_.node.on_pdos([this](std::span<const canopen::PdoInUse> pdos) { return use(pdos); });
  }

  // Before the loop starts, once the gateway is complete: the set values in force before the
  // bridge's last stop (ctx.set_values) go back into the RPDOs' image before their first frame.
  // From now on every change is kept. clear_momentary takes out what must never come back (a
  // command bit that was held at the moment of the stop).
  void restore(const std::function<void()>& clear_momentary) {
    persist_ = ctx_.set_values != nullptr && ctx_.is_master();
    if (!persist_) return;
    bool restored = false;
    for (auto& r : rpdos_) {
      const auto& def = *codec_.pdos()[r.pdo].def;
      const auto kept = ctx_.set_values->restored(ctx_.device.name, def.name);
      if (!kept) continue;
      if (kept->mapping != mapping_of(def)) {
        spdlog::warn("{}: the kept set values of {} are not restored: its mapping changed since", ctx_.device.name, def.name);
        continue;
      }
      if (auto ok = codec_.receive(r.pdo, kept->payload); !ok) continue;
      restored = true;
    }
    if (clear_momentary) clear_momentary();
    if (restored) spdlog::info("{}: set values in force restored from {}", ctx_.device.name, ctx_.set_values->path());
    keep();
  }
  // What a gateway learns about every frame of the RPDOs that carry one object (the control word,
  // for momentary commands), as the device's boot left them mapped.
  struct RpdoObserver {
    std::function<void()> before_send;  // a frame is about to be packed from the image
    std::function<void(std::chrono::steady_clock::time_point at)> sent;
    std::function<void(std::string_view why)> not_sent;  // one was due and did not go out
  };
  // Before the loop starts.
  void observe(std::uint16_t index, RpdoObserver observer) { observers_.push_back({index, std::move(observer)}); }

  // Loop thread.
  void on_sync() {
    for (auto& r : rpdos_) r.transmitter->on_sync();
  }
  void on_data() {
    for (auto& r : rpdos_) r.transmitter->on_data();
    keep();
  }
  void resend() {
    for (auto& r : rpdos_) r.transmitter->resend();
  }
  std::vector<Rpdo>& rpdos() { return rpdos_; }

 private:
  static canopen::PdoTransmitter::Settings settings(const profiles::DevicePdo& p) {
    return {p.can_id, p.extended, p.transmission_type, p.inhibit, p.event_timer};
  }

  static std::vector<std::uint32_t> mapping_of(const profiles::DevicePdo& p) {
    std::vector<std::uint32_t> m;
    for (const auto& e : p.mapping) m.push_back(e.to_u32());
    return m;
  }

  // The RPDOs' payloads as they would go out now.
  void keep() {
    if (!persist_) return;
    for (auto& r : rpdos_) {
      const auto& def = *codec_.pdos()[r.pdo].def;
      std::array<std::uint8_t, 8> data{};
      const auto len = codec_.pack(r.pdo, std::span<std::uint8_t, 8>(data));
      ctx_.set_values->save(ctx_.device.name, def.name, {mapping_of(def), {data.begin(), data.begin() + len}});
    }
  }

  bool may_send(std::size_t k) const {
    return rpdos_[k].valid_on_device && ctx_.node.ready_for_pdos() && (!gate_ || gate_());
  }

  // Why may_send(k) is false, for whoever waits for the frame.
  std::string why_not(std::size_t k) const {
    const auto& name = ctx_.device.name;
    const auto& node = ctx_.node;
    if (!rpdos_[k].valid_on_device) {
      return fmt::format("{} has {} disabled (COB-ID bit 31)", name, codec_.pdos()[rpdos_[k].pdo].def->name);
    }
    if (!node.online()) return name + " is offline (no heartbeat)";
    if (!node.configured()) return name + " has not passed its boot (its state became unknown, or the boot failed)";
    if (node.commanded_state() != canopen::NmtState::operational) return name + " was told to leave operational (NMT)";
    if (node.state() != canopen::NmtState::operational) {
      return fmt::format("{} reports {}, not operational", name, canopen::to_string(node.state()));
    }
    return name + ": the gateway does not send this PDO yet";
  }

  bool observed(std::size_t pdo) const {
    for (const auto& o : observers_) {
      if (maps(pdo, o.index)) return true;
    }
    return false;
  }
  bool maps(std::size_t pdo, std::uint16_t index) const {
    for (const auto& e : codec_.pdos()[pdo].binding.mapping().entries()) {
      if (e.index == index) return true;
    }
    return false;
  }
  template <class F>
  void notify(std::size_t pdo, F f) const {
    for (const auto& o : observers_) {
      if (maps(pdo, o.index)) f(o.observer);
    }
  }

  Result<void> use(std::span<const canopen::PdoInUse> pdos) {
    for (const auto& found : pdos) {
      for (std::size_t i = 0; i < codec_.pdos().size(); ++i) {
        const auto& configured = *codec_.pdos()[i].def;
        if (configured.name != found.name) continue;
        const auto actual = in_use(configured, found.parameters);
        const bool remapped = actual.mapping != configured.mapping;
        if (auto r = codec_.use_pdo(i, actual); !r) return r;
        if (remapped) {
          spdlog::info("{}: {} decoded and sent by the device's own mapping ({} objects)", ctx_.device.name, found.name,
                       actual.mapping.size());
        }
        for (auto& r : rpdos_) {
          if (r.pdo != i) continue;
          r.valid_on_device = actual.enabled;
          const auto s = settings(actual);
          const auto& old = r.transmitter->settings();
          if (s.transmission_type != old.transmission_type || s.can_id != old.can_id || s.extended != old.extended) {
            r.transmitter->reconfigure(s);
          }
        }
      }
    }
    return {};
  }

  const DeviceContext& ctx_;
  Codec& codec_;
  Gate gate_;
  std::vector<Rpdo> rpdos_;
  bool persist_ = false;
  struct Observer {
    std::uint16_t index;
    RpdoObserver observer;
  };
  std::vector<Observer> observers_;
};

}  // namespace lb::gateways
