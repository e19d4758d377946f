#pragma once
// A device's PDOs on its bus loop, the same for every gateway: the TPDOs it sends (and, on a
// monitor bus, the RPDOs a line controller sends it) handed to the gateway by PDO index; the
// RPDOs the bridge sends from the codec's image by their transmission type, only while the device
// may take them (master role); and the PDOs the device's boot left in use taken over before the
// device is started (pdo_config: adopt, or a PDO the device does not have).
// Codec: pdos() (each with `def`, the DevicePdo it decodes by, and `binding`), pack(i, out),
// use_pdo(i, DevicePdo).

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "canopen/node_driver.hpp"
#include "canopen/pdo_transmitter.hpp"
#include "gateways/node/device_context.hpp"
#include "gateways/node/pdo_specs.hpp"
#include "gateways/persistence/set_value_restore.hpp"

namespace lb::gateways {

template <class Codec>
class PdoWiring final : public canopen::NodeDriver {
 public:
  using Receive = std::function<void(std::size_t pdo, const can::CanFrame& frame)>;
  using Gate = std::function<bool()>;
  struct Rpdo {
    std::size_t pdo;  // index in the codec
    std::unique_ptr<canopen::PdoTransmitter> transmitter;
    bool valid_on_device = true;
  };

  // Before the loop starts. gate: the gateway's own condition for sending (besides the device's).
  PdoWiring(const DeviceContext& ctx, Codec& codec, const Receive& receive, Gate gate = {})
      : ctx_(ctx), codec_(codec), gate_(std::move(gate)) {
    for (std::size_t i = 0; i < codec_.pdos().size(); ++i) {
      const auto& pdo = *codec_.pdos()[i].def;
      if (!pdo.enabled) continue;  // COB-ID bit 31: this PDO does not exist on the bus
      if (pdo.direction == profiles::PdoDirection::tx || !ctx_.is_master()) {
        const auto handler = [receive, i](const can::CanFrame& f) { receive(i, f); };
        if (pdo.extended)
          ctx_.loop.on_extended_frame(pdo.can_id, handler);
        else
          ctx_.loop.on_frame(pdo.can_id, handler);
        continue;
      }
      const std::size_t k = rpdos_.size();
      using Transmitter = canopen::PdoTransmitter;
      rpdos_.push_back(
          {i,
           std::make_unique<Transmitter>(
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
      rpdos_.back().transmitter->quiet_until(ctx_.rpdos_from);
    }
    if (ctx_.is_master()) ctx_.node.attach(*this);
  }
  PdoWiring(const PdoWiring&) = delete;
  PdoWiring& operator=(const PdoWiring&) = delete;

  // NodeDriver (master role). The boot's PDOs are taken before the device is started.
  Result<void> on_config(std::span<const canopen::PdoInUse> pdos) noexcept override { return use(pdos); }
  // A boot-up (believed: canopen/remote_node) starts the device from its power-on PDOs; one that
  // was gone may come back as another device: its PDOs are verified again.
  void on_event(canopen::NodeEvent e) noexcept override {
    if (e == canopen::NodeEvent::boot_up || e == canopen::NodeEvent::lost) {
      pdos_verified_ = false;
      safe_image_asked_ = false;
    }
  }
  void on_start(const canopen::StartFacts& facts) noexcept override {
    if (restored_) starting(facts);
  }

  // Before the loop starts, once the gateway is complete (master role). clear_momentary takes out
  // what must never come back (a command bit that was held at the moment of the stop). From the
  // first start on, every change of the RPDOs' image is kept (ctx.set_values).
  // At every start of the device (right before NMT start) the start-up policy decides what its
  // RPDOs carry (set_value_restore.hpp): at the first start, the set values kept at the bridge's
  // last stop, if they were held in force recently enough, by a device of the same identity, and
  // pass today's range checks; at a later start (the device lost power or was reset while the
  // bridge ran), the image in force. Either way a device not found operational gets no enabling
  // level (restart_after_power_loss: never).
  void restore(std::function<void()> clear_momentary) {
    clear_momentary_ = std::move(clear_momentary);
    if (clear_momentary_) clear_momentary_();
    if (!ctx_.is_master()) return;
    persist_ = ctx_.set_values != nullptr;
    restored_ = true;
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

  // NodeDriver: the bus's SYNC (master role, where the bus produces it).
  void on_sync() noexcept override {
    for (auto& r : rpdos_) r.transmitter->on_sync();
  }
  // Loop thread.
  void on_data() {
    for (auto& r : rpdos_) r.transmitter->on_data();
    keep();
  }
  void resend() {
    for (auto& r : rpdos_) r.transmitter->resend();
  }
  std::vector<Rpdo>& rpdos() { return rpdos_; }

  // Loop thread. The RPDOs' image as it would go out now carries an enabling level (program on,
  // extruder running): what a device the bridge has not started (again) must not be sent.
  bool carries_enabling() {
    for (const auto& r : rpdos_) {
      auto data = payload(r);
      if (!clear_enabling(ctx_.profile, mapping_in_use(r), data).empty()) return true;
    }
    return false;
  }
  // Loop thread: every enabling level off in the image (a stop on a device the bridge does not
  // control just now); returns what was switched off.
  std::vector<std::string> switch_off_enabling() {
    std::vector<std::string> off;
    for (const auto& r : rpdos_) {
      auto data = payload(r);
      auto names = clear_enabling(ctx_.profile, mapping_in_use(r), data);
      if (names.empty() || !codec_.receive(r.pdo, data)) continue;
      off.insert(off.end(), names.begin(), names.end());
    }
    if (!off.empty()) on_data();
    return off;
  }
  // Loop thread, for a stopping command on a device the bridge has not started: true when its
  // RPDOs may carry the pulse now (heard running, PDOs verified), after every enabling level was
  // switched off in the image (a stop means stop: its RPDOs may carry nothing that enables).
  bool ready_for_a_stop() {
    if (!takes_a_safe_image()) return false;
    safe_image_asked_ = true;
    if (const auto off = switch_off_enabling(); !off.empty()) {
      spdlog::warn("{}: a stop for a device the bridge has not started: switched off first: {}", ctx_.device.name,
                   fmt::join(off, ", "));
    }
    return true;
  }
  using Image = std::vector<std::vector<std::uint8_t>>;
  // Loop thread: the RPDOs' payloads, to put back what a refused change did.
  Image image() {
    Image out;
    for (const auto& r : rpdos_) out.push_back(payload(r));
    return out;
  }
  void restore_image(const Image& image) {
    for (std::size_t k = 0; k < rpdos_.size() && k < image.size(); ++k)
      static_cast<void>(codec_.receive(rpdos_[k].pdo, image[k]));
  }
  // Loop thread: a device the bridge has not started (its boot under way, failed, or its state
  // unknown) that is heard operational and whose PDOs a boot of this run verified: it may take an
  // image that enables nothing, so a stop is never held back while it is heard.
  bool takes_a_safe_image() const {
    return pdos_verified_ && ctx_.node.online() && ctx_.node.state() == canopen::NmtState::operational;
  }
  // Loop thread: an operator's set value that enables nothing was taken for such a device: from
  // now on its RPDOs carry the image while it enables nothing (never by themselves: a restarted
  // bridge whose boot fails must not stop a running line unasked).
  void safe_image_asked() { safe_image_asked_ = true; }

 private:
  static canopen::PdoTransmitter::Settings settings(const profiles::DevicePdo& p) {
    return {p.can_id, p.extended, p.transmission_type, p.inhibit, p.event_timer};
  }

  static std::vector<std::uint32_t> mapping_of(const profiles::DevicePdo& p) {
    std::vector<std::uint32_t> m;
    for (const auto& e : p.mapping) m.push_back(e.to_u32());
    return m;
  }

  SetValueStore::Key store_key(const profiles::DevicePdo& def) const {
    return {ctx_.bus.name, ctx_.device.node_id, ctx_.profile.key(), def.name};
  }

  // The RPDOs' payloads as they would go out now; only once a start has decided what they are.
  void keep() {
    if (!persist_ || !started_once_) return;
    for (auto& r : rpdos_) {
      const auto& def = *codec_.pdos()[r.pdo].def;
      ctx_.set_values->save(store_key(def), {identity_, 0, mapping_of(def), payload(r)});
    }
  }

  // The RPDO's payload as it would go out now, and the mapping it goes out by (the device's, after
  // its boot).
  std::vector<std::uint8_t> payload(const Rpdo& r) {
    std::array<std::uint8_t, 8> data{};
    const auto len = codec_.pack(r.pdo, std::span<std::uint8_t, 8>(data));
    return {data.begin(), data.begin() + len};
  }
  const canopen::PdoMapping& mapping_in_use(const Rpdo& r) const { return codec_.pdos()[r.pdo].binding.mapping(); }

  // Why a kept entry does not go back into this device, or nothing when it may.
  std::optional<std::string> refuse_kept(const Rpdo& r, const SetValueStore::Entry& kept) const {
    const auto& def = *codec_.pdos()[r.pdo].def;
    if (kept.mapping != mapping_of(def)) return "its mapping changed since";
    if (kept.identity != identity_) {
      return fmt::format(
          "they were kept for another device (identity {:08X}:{:08X}:{:08X}:{:08X}, now {:08X}:{:08X}:{:08X}:{:08X})",
          kept.identity[0], kept.identity[1], kept.identity[2], kept.identity[3], identity_[0], identity_[1],
          identity_[2], identity_[3]);
    }
    const auto now =
        std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
    const auto age = now - kept.held_at_s;
    // A stamp from the future: the clock went back, so the age is unknown.
    if (age < -60) return fmt::format("they are stamped {} s in the future (the clock went back?)", -age);
    if (age > ctx_.startup.set_values_max_age.count()) {
      return fmt::format("they were last in force {} s ago, over set_values_max_age_s {}", age,
                         ctx_.startup.set_values_max_age.count());
    }
    if (auto ok = check_set_values(ctx_.profile, mapping_in_use(r), kept.payload); !ok)
      return "out of range: " + ok.error().message;
    return std::nullopt;
  }

  // Loop thread, right before the device's NMT start.
  void starting(const canopen::StartFacts& facts) {
    identity_ = facts.identity;
    safe_image_asked_ = false;
    const auto scope = restore_scope(ctx_.startup, facts.found_operational, ctx_.device.starts_itself);
    const bool first = !started_once_;
    started_once_ = true;
    std::vector<std::string> notes;
    std::vector<std::string> cleared;
    for (auto& r : rpdos_) {
      const auto& def = *codec_.pdos()[r.pdo].def;
      std::vector<std::uint8_t> data;
      if (first) {
        // The image is all zero until now: what comes back is what was kept.
        const auto kept = ctx_.set_values != nullptr ? ctx_.set_values->restored(store_key(def)) : std::nullopt;
        if (!kept) continue;
        if (const auto why = refuse_kept(r, *kept)) {
          notes.push_back(fmt::format("{} not restored: {}", def.name, *why));
          continue;
        }
        data = kept->payload;
        notes.push_back(fmt::format("{} restored", def.name));
      } else {
        data = payload(r);
      }
      if (scope == RestoreScope::nothing) std::fill(data.begin(), data.end(), std::uint8_t{0});
      if (scope == RestoreScope::non_enabling) {
        for (auto& name : clear_enabling(ctx_.profile, mapping_in_use(r), data)) cleared.push_back(std::move(name));
      }
      if (auto ok = codec_.receive(r.pdo, data); !ok)
        notes.push_back(fmt::format("{}: {}", def.name, ok.error().message));
    }
    if (clear_momentary_) clear_momentary_();
    const char* found = facts.found_operational ? (ctx_.device.starts_itself ? "found operational, but it starts itself"
                                                                             : "found operational")
                                                : "found not operational (power loss or reset)";
    std::string note = fmt::format("{}: {} set values", found, to_string(scope));
    if (!cleared.empty())
      note += fmt::format("; enabling levels switched off until an operator sets them: {}", fmt::join(cleared, ", "));
    if (!notes.empty()) note += fmt::format("; {}", fmt::join(notes, "; "));
    if (!cleared.empty())
      spdlog::warn("{}: {}", ctx_.device.name, note);
    else if (first || scope == RestoreScope::nothing)
      spdlog::info("{}: {}", ctx_.device.name, note);
    ctx_.node.note_set_values_at_start(std::move(note));
    keep();
  }

  bool may_send(std::size_t k) {
    if (!rpdos_[k].valid_on_device || (gate_ && !gate_())) return false;
    return ctx_.node.ready_for_pdos() || (safe_image_asked_ && takes_a_safe_image() && !carries_enabling());
  }

  // Why may_send(k) is false, for whoever waits for the frame.
  std::string why_not(std::size_t k) {
    const auto& name = ctx_.device.name;
    const auto& node = ctx_.node;
    if (!rpdos_[k].valid_on_device) {
      return fmt::format("{} has {} disabled (COB-ID bit 31)", name, codec_.pdos()[rpdos_[k].pdo].def->name);
    }
    if (!node.online()) return name + " is offline (no heartbeat)";
    if (!node.configured()) {
      if (takes_a_safe_image()) {
        return name +
               " has not passed its boot (its state became unknown, or the boot failed): while it runs it takes only "
               "set values that enable nothing (program off, extruder stopped)";
      }
      return name + " has not passed its boot (its state became unknown, or the boot failed)";
    }
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
    pdos_verified_ = true;
    return {};
  }

  const DeviceContext& ctx_;
  Codec& codec_;
  Gate gate_;
  std::vector<Rpdo> rpdos_;
  bool persist_ = false;
  bool restored_ = false;                    // restore() was called: each start decides the image
  bool started_once_ = false;                // loop thread: a start has decided the image
  bool pdos_verified_ = false;               // loop thread: a boot checked the device's PDOs since its last boot-up
  bool safe_image_asked_ = false;            // loop thread: an operator stopped a device the bridge has not started
  std::array<std::uint32_t, 4> identity_{};  // loop thread: 1018h of the device as its last boot read it
  std::function<void()> clear_momentary_;
  struct Observer {
    std::uint16_t index;
    RpdoObserver observer;
  };
  std::vector<Observer> observers_;
};

}  // namespace lb::gateways
