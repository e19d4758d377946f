#pragma once
// The one owner of a device's output in the master role: its RPDO image and what of it may go out,
// the same for every behaviour (drive, saw, feeder and any type to come) by construction. Nothing
// else writes the image. Every change passes through one of three doors:
//   - an operator's change taken in this run: a set value (take) or a momentary command (press);
//   - a start of the device (starting: the start-up policy, one function for every start: the
//     first boot, the device power-cycled alone, back after a loss, a reset, a bridge restart),
//     which knows from the profile's `enabling` marks what enables motion;
//   - a stop: a set value that writes 0 to an enabling level and non-zero to none (program off,
//     extruder stopped, loom_status stop), or a command the profile marks `stopping`. A stop goes
//     out at once whenever the device is heard (RemoteNode::heard: any frame of its own within its
//     heartbeat timeout), whatever the node state machine, its boot, its identity check or another
//     master's SYNC says, and is answered accepted only once its frame is on the bus; one that
//     cannot go out is refused with the reason.
// What it keeps: which RPDOs an operator wrote in this run (never replaced by a kept value), the
// set values in force (SetValueStore, from the first start on), and whether an operator's stop put
// a device the bridge does not control just now in stop mode (its RPDOs then go out while it is
// heard and the image enables nothing).
//
// It also wires the device's TPDOs (and, on a monitor bus, the RPDOs a line controller sends) to
// the gateway by PDO index, and takes over the PDOs the device's boot left in use before it is
// started. Loop thread throughout, but the constructor (before the loop starts).
// Codec: pdos() (each with `def`, the DevicePdo, and `binding`), pack(i, out), receive(i, payload),
// use_pdo(i, DevicePdo); set_control_bit(bit, on) where the device has momentary commands.

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

#include "base/journal_event.hpp"
#include "canopen/node_driver.hpp"
#include "canopen/pdo_transmitter.hpp"
#include "gateways/node/command_bits.hpp"
#include "gateways/node/device_context.hpp"
#include "gateways/node/momentary_commands.hpp"
#include "gateways/node/pdo_specs.hpp"
#include "gateways/node/rpdo_read_back.hpp"
#include "gateways/persistence/set_value_restore.hpp"

namespace lb::gateways {

template <class Codec>
class DeviceOutput final : public canopen::NodeDriver {
 public:
  using Receive = std::function<void(std::size_t pdo, const can::CanFrame& frame)>;
  // An operator's change was taken (accepted) or refused, with the reason (empty when none).
  using Taken = std::function<void(bool accepted, const std::string& reason)>;
  struct Options {
    // The momentary commands of its control word (command_bits.hpp); none for a device without.
    std::vector<CommandBit> commands;
    // Its RPDOs stay silent until an operator's first change in this run: the feeder box, whose
    // RPDOs a loom controller normally drives (only one may drive a bus).
    bool silent_until_told = false;
    // A change that is not a stop is refused unless the device runs, started by this bridge: the
    // feeder box's triggers and picks are events, worthless once late.
    bool refuse_unless_started = false;
    // Which RPDOs carry a state, sent again when the device's NMT state or online flag changes
    // (null: all); the others carry events, never repeated.
    std::function<bool(std::size_t pdo)> state_pdo;
  };
  struct Rpdo {
    std::size_t pdo;  // index in the codec
    std::unique_ptr<canopen::PdoTransmitter> transmitter;
    bool valid_on_device = true;
    bool told = false;    // an operator wrote it in this run: no kept value ever replaces it
    bool silent = false;  // a restarted bridge does not know what the device holds: not sent until told
    std::string silent_why;
    bool seen = false;          // standby: the master's frame of it was seen on the bus (its image holds it)
    bool seen_refused = false;  // standby: a frame of it the codec refused was reported
  };

  // Before the loop starts. changed: the image changed (the gateway publishes its status).
  DeviceOutput(const DeviceContext& ctx, Codec& codec, const Receive& receive, Options options,
               std::function<void()> changed)
      : ctx_(ctx), codec_(codec), options_(std::move(options)), changed_(std::move(changed)) {
    for (std::size_t i = 0; i < codec_.pdos().size(); ++i) {
      const auto& pdo = *codec_.pdos()[i].def;
      if (!pdo.enabled) continue;  // COB-ID bit 31: this PDO does not exist on the bus
      if (pdo.direction == profiles::PdoDirection::tx || !ctx_.is_master()) {
        const bool own = pdo.direction == profiles::PdoDirection::tx;
        const auto handler = [this, receive, i, own](const can::CanFrame& f) {
          if (own) ctx_.node.heard_frame(f.timestamp_ns);  // a TPDO is the device's own: it is heard
          receive(i, f);
        };
        if (pdo.extended)
          ctx_.loop.on_extended_frame(pdo.can_id, handler);
        else
          ctx_.loop.on_frame(pdo.can_id, handler);
        continue;
      }
      add_rpdo(i, pdo);
      // A standby keeps what the master puts on the bus, as the device got it: the image a
      // takeover goes on sending (docs/redundancy.md).
      if (observing_) {
        const auto k = rpdos_.size() - 1;
        const auto seen = [this, k](const can::CanFrame& f) { observe(k, f); };
        if (pdo.extended)
          ctx_.loop.on_extended_frame(pdo.can_id, seen);
        else
          ctx_.loop.on_frame(pdo.can_id, seen);
      }
    }
    if constexpr (requires(Codec & c) { c.set_control_bit(0U, false); }) {
      if (!options_.commands.empty()) {
        pulses_.emplace(
            ctx_.loop, [this](unsigned bit, bool on) { codec_.set_control_bit(bit, on); }, [this] { image_changed(); });
      }
    }
    clear_momentary();
    if (ctx_.is_master()) {
      persist_ = ctx_.set_values != nullptr;
      ctx_.node.attach(*this);
    }
  }
  DeviceOutput(const DeviceOutput&) = delete;
  DeviceOutput& operator=(const DeviceOutput&) = delete;

  // ---- NodeDriver (master role) ----
  // The boot's PDOs are taken before the device is started.
  Result<void> on_config(std::span<const canopen::PdoInUse> pdos) noexcept override { return use(pdos); }
  // A device that booted runs nothing an operator's stop asked for any more (one whose heartbeat
  // was lost may still be heard: a stop in progress goes on while it is).
  void on_event(canopen::NodeEvent e) noexcept override {
    if (e == canopen::NodeEvent::boot_up) stop_mode_ = false;
  }
  void on_start(const canopen::StartFacts& facts) noexcept override { starting(facts); }
  void on_sync() noexcept override {
    for (auto& r : rpdos_) r.transmitter->on_sync();
  }
  // A device (re)started, stopped or back online gets its state again at once.
  void on_nmt_change(canopen::NmtState, bool) noexcept override {
    for (auto& r : rpdos_) {
      if (!options_.state_pdo || options_.state_pdo(r.pdo)) r.transmitter->resend();
    }
  }

  // ---- an operator's changes (loop thread) ----
  // A set value: apply() writes it into the codec's image (it may be called more than once: a
  // change is tried on copies first to tell a stop from a switch-on). resend: codec PDO indices
  // sent even when unchanged (an event that repeats).
  template <class Apply>
  void take(Apply apply, const Taken& taken, std::span<const std::size_t> resend = {}) {
    const auto change = classify(apply);
    const auto& name = ctx_.device.name;
    if (change.stops) return take_stop(apply, change, taken, resend);
    if (ctx_.loop.transmission_held()) return taken(false, ctx_.another_master("set value not applied"));
    if (!ctx_.node.online()) return taken(false, name + " is offline (no heartbeat): set value not applied");
    if (options_.refuse_unless_started && !ctx_.node.ready_for_pdos()) {
      return taken(false, name + " is not started by this bridge or offline: set value not sent");
    }
    if (!ctx_.node.configured() && change.enables) {
      return taken(false, name + " has not passed its boot (see its info topic): a set value that switches it on is "
                                 "refused (one that enables nothing is taken)");
    }
    write(apply, change, resend);
    flush();
    taken(true, ctx_.node.configured() ? "" : name + " has not passed its boot: taken, sent once it is started");
  }

  // A momentary command: refuse(reason) at once, or done(outcome) once the pulse is over. A
  // stopping one goes out whenever the device is heard (its first frame at once), after every
  // enabling level was switched off where the bridge does not control the device just now.
  void press(const CommandBit& c, const std::function<void(const std::string&)>& refuse, MomentaryCommands::Done done) {
    const auto& name = ctx_.device.name;
    if (!pulses_) return refuse(name + " has no momentary commands");
    if (!c.stopping) {
      if (ctx_.loop.transmission_held()) return refuse(ctx_.another_master(c.name + " not sent"));
      if (!ctx_.node.online()) return refuse(name + " is offline (no heartbeat): " + c.name + " not sent");
      if (!ctx_.node.ready_for_pdos()) {
        return refuse(name + " is not started by this bridge (its boot has not passed, or it was told to stop): " +
                      c.name + " not sent");
      }
      if (const auto why = silent_reason(); !why.empty()) return refuse(why + ": " + c.name + " not sent");
      return pulses_->press(c.bit, std::move(done));
    }
    if (!ctx_.node.heard_now()) return refuse(not_heard(c.name));
    if (!carrier()) return refuse(name + ": no RPDO in use carries the control word: " + c.name + " not sent");
    quiet_ = true;  // the press's own frame goes out below, once
    if (!ctx_.node.ready_for_pdos() || ctx_.loop.transmission_held() || carrier()->silent) {
      stop_mode_ = true;
      fill_undecided();
      if (const auto off = switch_off_enabling(); !off.empty()) {
        spdlog::warn("{}: {} for a device the bridge does not control just now: switched off first: {}", name, c.name,
                     fmt::join(off, ", "));
      }
    }
    // Until this pulse is over its frames go out while the device is heard, whatever its state is
    // believed to be meanwhile: the stop carries the image the device runs with, plus the stop.
    ++stop_pulses_;
    pulses_->press(c.bit, [this, done = std::move(done)](const MomentaryCommands::Outcome& o) {
      --stop_pulses_;
      if (done) done(o);
    });
    quiet_ = false;
    for (auto& r : rpdos_) {
      if (r.valid_on_device && carries_control_word(r)) {
        r.told = true;
        r.silent = false;
        static_cast<void>(r.transmitter->send_now());  // a refusal reaches the pulse (not_sent)
      }
    }
    after_change();
  }

  // The image changed by a pulse or a change: event-driven RPDOs go now, the rest at their SYNC.
  // While another master holds the bus the bridge runs no SYNC: a stop's frames go at once.
  void flush() {
    if (stop_mode_ && ctx_.loop.transmission_held()) {
      for (auto& r : rpdos_) {
        if (r.valid_on_device && !r.silent && (told_any_ || !options_.silent_until_told) && !carries_enabling())
          static_cast<void>(r.transmitter->send_now());
      }
    } else {
      for (auto& r : rpdos_) r.transmitter->on_data();
    }
    after_change();
  }

  const std::vector<Rpdo>& rpdos() const { return rpdos_; }

 private:
  struct Change {
    std::vector<bool> touched;  // per RPDO: the change writes some of its bytes
    bool stops = false;         // writes 0 to an enabling level and non-zero to none
    bool enables = false;       // writes non-zero to an enabling level
  };
  using Image = std::vector<std::vector<std::uint8_t>>;

  void add_rpdo(std::size_t i, const profiles::DevicePdo& pdo) {
    const std::size_t k = rpdos_.size();
    using Transmitter = canopen::PdoTransmitter;
    rpdos_.push_back(
        {i,
         std::make_unique<Transmitter>(
             ctx_.loop, settings(pdo),
             Transmitter::Hooks{
                 .pack = [this, i](can::CanFrame& f) { f.len = codec_.pack(i, std::span<std::uint8_t, 8>(f.data)); },
                 .may_send = [this, k] { return may_send(k); },
                 .before_send =
                     [this, k] {
                       if (pulses_ && carries_control_word(rpdos_[k])) pulses_->before_frame();
                     },
                 .sent =
                     [this, k](const can::CanFrame&, std::chrono::steady_clock::time_point at) {
                       ++ctx_.node.stats().pdos_sent;
                       if (pulses_ && carries_control_word(rpdos_[k])) pulses_->frame_sent(at);
                     },
                 .not_sent =
                     [this, k](Transmitter::Refusal why) {
                       if (!pulses_ || !carries_control_word(rpdos_[k])) return;
                       // Held back while another master holds the bus, not refused: a stop's own
                       // frames go out at once (flush), a timer releases its pulse.
                       if (ctx_.loop.transmission_held() && stop_mode_) return;
                       if (ctx_.node.boot_up_pending()) return;  // held back until it is judged
                       pulses_->frame_not_sent(why == Transmitter::Refusal::bus
                                                   ? std::string("the bus refused the frame (diagnostics: tx_dropped)")
                                                   : why_not(k));
                     },
                 .stopping = [this, k] { return stopping(k); }}),
         true,
         false,
         false,
         {}});
    rpdos_.back().transmitter->quiet_until(ctx_.rpdos_from);
  }

  static canopen::PdoTransmitter::Settings settings(const profiles::DevicePdo& p) {
    return {p.can_id, p.extended, p.transmission_type, p.inhibit, p.event_timer};
  }
  static std::vector<std::uint32_t> mapping_of(const profiles::DevicePdo& p) {
    std::vector<std::uint32_t> m;
    for (const auto& e : p.mapping) m.push_back(e.to_u32());
    return m;
  }
  const profiles::DevicePdo& def(const Rpdo& r) const { return *codec_.pdos()[r.pdo].def; }
  const canopen::PdoMapping& mapping(const Rpdo& r) const { return codec_.pdos()[r.pdo].binding.mapping(); }
  SetValueStore::Key store_key(const Rpdo& r) const {
    return {ctx_.bus.name, ctx_.device.node_id, ctx_.profile.key(), def(r).name};
  }
  bool carries_control_word(const Rpdo& r) const {
    const auto* cw = ctx_.profile.object("control_word");
    if (cw == nullptr) return false;
    const auto entries = mapping(r).entries();
    return std::any_of(entries.begin(), entries.end(), [cw](const auto& e) { return e.index == cw->index; });
  }
  const Rpdo* carrier() const {
    for (const auto& r : rpdos_) {
      if (r.valid_on_device && carries_control_word(r)) return &r;
    }
    return nullptr;
  }

  // The RPDO's payload as it would go out now.
  std::vector<std::uint8_t> payload(const Rpdo& r) const {
    std::array<std::uint8_t, 8> data{};
    const auto len = codec_.pack(r.pdo, std::span<std::uint8_t, 8>(data));
    return {data.begin(), data.begin() + len};
  }
  Image image() const {
    Image out;
    for (const auto& r : rpdos_) out.push_back(payload(r));
    return out;
  }
  void restore_image(const Image& image) {
    for (std::size_t k = 0; k < rpdos_.size() && k < image.size(); ++k)
      static_cast<void>(codec_.receive(rpdos_[k].pdo, image[k]));
  }

  // What a change writes, found by trying it on two copies of the image, every RPDO byte all ones
  // and all zeros: a byte it writes differs from one of them, and an enabling level it writes
  // reads the same in both. The image is put back as it was.
  template <class Apply>
  Change classify(Apply& apply) {
    const auto before = image();
    Change c;
    c.touched.assign(rpdos_.size(), false);
    Image forced[2];
    for (int pass = 0; pass < 2; ++pass) {
      Image pattern;
      for (const auto& p : before) pattern.emplace_back(p.size(), pass == 0 ? 0xFF : 0x00);
      restore_image(pattern);
      apply();
      forced[pass] = image();
      for (std::size_t k = 0; k < rpdos_.size(); ++k) {
        if (forced[pass][k] != pattern[k]) c.touched[k] = true;
      }
    }
    restore_image(before);
    bool zero_written = false;
    for (std::size_t k = 0; k < rpdos_.size(); ++k) {
      const auto ones = enabling_levels(ctx_.profile, mapping(rpdos_[k]), forced[0][k]);
      const auto zeros = enabling_levels(ctx_.profile, mapping(rpdos_[k]), forced[1][k]);
      for (std::size_t f = 0; f < ones.size() && f < zeros.size(); ++f) {
        if (ones[f].value == 0) zero_written = true;  // forced on, and the change put it off
        if (zeros[f].value != 0) c.enables = true;    // forced off, and the change put it on
      }
    }
    c.stops = zero_written && !c.enables;
    return c;
  }

  template <class Apply>
  void write(Apply& apply, const Change& change, std::span<const std::size_t> resend) {
    apply();
    told_any_ = true;
    for (std::size_t k = 0; k < rpdos_.size(); ++k) {
      auto& r = rpdos_[k];
      const bool again = std::find(resend.begin(), resend.end(), r.pdo) != resend.end();
      if (!change.touched[k] && !again) continue;
      r.told = true;
      r.silent = false;
      if (again) r.transmitter->resend();
    }
  }

  template <class Apply>
  void take_stop(Apply& apply, const Change& change, const Taken& taken, std::span<const std::size_t> resend) {
    const auto& name = ctx_.device.name;
    if (!ctx_.node.heard_now()) return taken(false, not_heard("set value"));
    fill_undecided();
    write(apply, change, resend);
    if (!ctx_.node.ready_for_pdos() || ctx_.loop.transmission_held()) stop_mode_ = true;
    std::string failed;
    unsigned sent = 0;
    for (std::size_t k = 0; k < rpdos_.size(); ++k) {
      auto& r = rpdos_[k];
      if (!change.touched[k]) continue;
      if (!r.valid_on_device) {
        failed += fmt::format("{}{} is disabled on the device (COB-ID bit 31)", failed.empty() ? "" : "; ",
                              def(r).name);
        continue;
      }
      if (auto ok = r.transmitter->send_now(); !ok) {
        failed += fmt::format("{}{}: {}", failed.empty() ? "" : "; ", def(r).name, ok.error().message);
        continue;
      }
      ++sent;
    }
    after_change();
    if (sent == 0) {
      return taken(false, name + ": the stop could not go out (" + (failed.empty() ? "no RPDO carries it" : failed) +
                              "); its image holds it and goes out as soon as it can");
    }
    taken(true, failed.empty() ? "" : "on the bus, but: " + failed);
  }

  // The image changed outside take(): a pulse set or released a bit.
  void image_changed() {
    if (quiet_) return;
    flush();
  }
  void after_change() {
    keep();
    if (changed_) changed_();
  }

  std::string not_heard(std::string_view what) const {
    return fmt::format("{} is not heard (no frame of its own within its heartbeat timeout of {} ms): the stop cannot "
                       "reach it; {} not sent",
                       ctx_.device.name, ctx_.node.heartbeat_timeout().count(), what);
  }
  // Why an RPDO that carries the control word is kept silent, or empty.
  std::string silent_reason() const {
    const auto* r = carrier();
    if (r == nullptr || !r->silent) return {};
    return ctx_.device.name + ": " + r->silent_why;
  }

  bool carries_enabling() const {
    for (const auto& r : rpdos_) {
      for (const auto& l : enabling_levels(ctx_.profile, mapping(r), payload(r))) {
        if (l.value != 0) return true;
      }
    }
    return false;
  }
  // Every enabling level off in the image; returns what was switched off.
  std::vector<std::string> switch_off_enabling() {
    std::vector<std::string> off;
    for (auto& r : rpdos_) {
      auto data = payload(r);
      auto names = clear_enabling(ctx_.profile, mapping(r), data);
      if (names.empty() || !codec_.receive(r.pdo, data)) continue;
      r.told = true;
      r.silent = false;
      off.insert(off.end(), names.begin(), names.end());
    }
    return off;
  }
  // Before a stop's frame for an RPDO no start has decided yet (a restarted bridge still booting the
  // device) or kept silent: the kept values, where their mapping is the one in use and they pass
  // today's range checks, so that the stop carries the device's last speeds and lengths rather
  // than zeros. Whatever comes back of them, the stop's own switch-off follows.
  void fill_undecided() {
    if (ctx_.set_values == nullptr) return;
    for (auto& r : rpdos_) {
      if (r.told || (started_once_ && !r.silent)) continue;
      const auto kept = ctx_.set_values->restored(store_key(r));
      if (!kept || kept->mapping != mapping_of(def(r)) || !check_set_values(ctx_.profile, mapping(r), kept->payload))
        continue;
      static_cast<void>(codec_.receive(r.pdo, kept->payload));
      clear_momentary();
    }
  }
  void clear_momentary() {
    if constexpr (requires(Codec & c) { c.set_control_bit(0U, false); }) {
      for (const auto& c : options_.commands) codec_.set_control_bit(c.bit, false);
    }
  }

  // The set values in force, from the first start on; an RPDO kept silent is not the device's.
  void keep() {
    if (!persist_ || !started_once_) return;
    for (auto& r : rpdos_) {
      if (r.silent) continue;
      ctx_.set_values->save(store_key(r), {identity_, 0, mapping_of(def(r)), payload(r)});
    }
  }

  // Why a kept entry does not go back into this device, or nothing when it may.
  std::optional<std::string> refuse_kept(const Rpdo& r, const SetValueStore::Entry& kept) const {
    if (kept.mapping != mapping_of(def(r))) return "its mapping changed since";
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
    if (auto ok = check_set_values(ctx_.profile, mapping(r), kept.payload); !ok)
      return "out of range: " + ok.error().message;
    return std::nullopt;
  }
  // Values were kept for the RPDO, and refuse_kept() refused them.
  bool kept_refused(const Rpdo& r, const Result<std::vector<std::uint8_t>>& kept) const {
    return !kept && ctx_.set_values != nullptr && ctx_.set_values->restored(store_key(r)).has_value();
  }
  // The kept payload of an RPDO if it may go back, else why not.
  Result<std::vector<std::uint8_t>> kept_payload(const Rpdo& r) const {
    const auto kept = ctx_.set_values != nullptr ? ctx_.set_values->restored(store_key(r)) : std::nullopt;
    if (!kept) return make_error(ctx_.set_values != nullptr ? "none kept" : "no state_dir");
    if (const auto why = refuse_kept(r, *kept)) return make_error(*why);
    return kept->payload;
  }
  // Per mapping entry: whether the device can be asked for it (dummies need no asking).
  std::vector<bool> readable_entries(const Rpdo& r) const {
    std::vector<bool> out;
    for (const auto& e : mapping(r).entries()) {
      const auto* obj = e.is_dummy() ? nullptr : ctx_.profile.object(e.index, e.sub);
      out.push_back(e.is_dummy() || (obj != nullptr && obj->readable()));
    }
    return out;
  }
  // Some mapped object (not a dummy) the device can be asked for.
  bool partly_readable(const Rpdo& r) const {
    const auto entries = mapping(r).entries();
    const auto read = readable_entries(r);
    for (std::size_t i = 0; i < read.size(); ++i) {
      if (read[i] && !entries[i].is_dummy()) return true;
    }
    return false;
  }

  // The start-up policy, right before the device's NMT start, at every start. What its RPDOs carry:
  // found running (only the bridge restarted, a heartbeat lost and back), what it had: at this
  // process's first start what the device holds (read back), else the kept values, else nothing
  // (the RPDO stays silent: the device keeps what it last received); later, the image in force.
  // Not found running (power loss, reset, boot-up) or paused by its boot: what enables nothing,
  // from the image in force or, at the first start, the kept values. An RPDO an operator wrote in
  // this run keeps what they wrote; only the enabling levels follow the policy.
  void starting(const canopen::StartFacts& facts) {
    observing_ = false;  // from its first start on, this bridge masters the bus: the image is its own
    if (facts.adopted) return adopting();
    identity_ = facts.identity;
    stop_mode_ = false;
    ++start_generation_;
    const auto scope = restore_scope(ctx_.startup, facts.found_operational, ctx_.device.starts_itself,
                                     facts.paused_by_boot);
    const bool first = !started_once_;
    started_once_ = true;
    std::vector<std::string> notes;
    std::vector<std::string> cleared;
    std::vector<std::string> refused;  // RPDOs whose kept values were refused (refuse_kept)
    std::vector<std::size_t> read_back;
    std::vector<std::vector<std::uint8_t>> read_base;  // per read_back: the kept values of write-only objects
    for (std::size_t k = 0; k < rpdos_.size(); ++k) {
      auto& r = rpdos_[k];
      const auto& name = def(r).name;
      auto data = payload(r);
      if (first && !r.told) {
        auto kept = kept_payload(r);
        if (scope == RestoreScope::all) {
          // What the device holds beats any file: the file may lag the last change (it is written
          // after the answer; a kill -9 right after an operator's program-off loses it). Objects
          // the profile makes write-only come from the kept values, when there are any.
          const auto read = readable_entries(r);
          const bool all_readable = std::ranges::all_of(read, [](bool b) { return b; });
          if (ctx_.sdo != nullptr && (all_readable || (kept && partly_readable(r)))) {
            r.silent = true;
            r.silent_why = name + " is being read back from the device (the bridge restarted while it ran)";
            read_back.push_back(k);
            read_base.push_back(all_readable ? std::vector<std::uint8_t>{} : *kept);
            if (!kept) notes.push_back(fmt::format("{}: kept values not used ({})", name, kept.error().message));
            continue;
          }
          if (!kept) {
            if (kept_refused(r, kept)) refused.push_back(name);
            keep_silent(r, fmt::format("{} not restored ({}) and not readable", name, kept.error().message));
            notes.push_back(r.silent_why + ": kept silent, the device keeps what it last received");
            continue;
          }
          data = *kept;
          notes.push_back(name + " restored");
        } else if (kept) {
          data = *kept;
          notes.push_back(name + " restored");
        } else {
          if (kept_refused(r, kept)) refused.push_back(name);
          notes.push_back(fmt::format("{} not restored: {}", name, kept.error().message));
        }
      }
      if (scope == RestoreScope::nothing) std::fill(data.begin(), data.end(), std::uint8_t{0});
      if (scope == RestoreScope::non_enabling) {
        for (auto& n : clear_enabling(ctx_.profile, mapping(r), data)) cleared.push_back(std::move(n));
      }
      if (data == payload(r)) continue;
      if (auto ok = codec_.receive(r.pdo, data); !ok) notes.push_back(fmt::format("{}: {}", name, ok.error().message));
    }
    clear_momentary();
    const char* found = facts.paused_by_boot        ? "found operational, paused to write its PDO parameters"
                        : !facts.found_operational  ? "found not operational (power loss or reset)"
                        : ctx_.device.starts_itself ? "found operational, but it starts itself"
                                                    : "found operational";
    std::string note = fmt::format("{}: {} set values", found, to_string(scope));
    if (!cleared.empty())
      note += fmt::format("; enabling levels switched off until an operator sets them: {}", fmt::join(cleared, ", "));
    if (!read_back.empty()) note += "; reading back what it holds";
    if (!notes.empty()) note += fmt::format("; {}", fmt::join(notes, "; "));
    if (!cleared.empty() || !refused.empty()) {  // a key event (base/journal_event)
      journal::log(journal::Event::set_values_refused, spdlog::level::warn, ctx_.node.where(),
                   fmt::format("{}: {}", ctx_.device.name, note),
                   {{journal::kRestoreScope, std::string(to_string(scope))},
                    {journal::kEnablingOff, fmt::format("{}", fmt::join(cleared, ","))},
                    {journal::kKeptRefused, fmt::format("{}", fmt::join(refused, ","))}});
    } else if (first || scope == RestoreScope::nothing) {
      spdlog::info("{}: {}", ctx_.device.name, note);
    }
    ctx_.node.note_set_values_at_start(note);
    keep();
    for (std::size_t i = 0; i < read_back.size(); ++i) start_read_back(read_back[i], note, read_base[i]);
  }

  // A standby's frame of the master's: the device got this payload; the image takes it as it is.
  void observe(std::size_t k, const can::CanFrame& f) {
    if (!observing_) return;
    auto& r = rpdos_[k];
    if (auto ok = codec_.receive(r.pdo, std::span<const std::uint8_t>(f.data.data(), f.len)); !ok) {
      if (!r.seen_refused) {
        spdlog::warn("{}: {} on the bus not taken by the standby: {}", ctx_.device.name, def(r).name,
                     ok.error().message);
      }
      r.seen_refused = true;
      return;
    }
    r.seen = true;
    r.told = true;  // in force on the device: a start after a takeover (a boot) takes it, not a file's value
  }

  // The start of a standby that took the bus over, for a device it adopts as it runs: each RPDO
  // goes on with what the master before put on the bus last (the set values in force, as the
  // device has them), momentary commands released, never pressed again; an RPDO not seen on the
  // bus stays silent (the device keeps what it last received). Nothing from a file.
  void adopting() {
    ++start_generation_;
    stop_mode_ = false;
    started_once_ = true;
    identity_ = {};  // not read: the kept values of this run name no device (a later restart reads back)
    std::vector<std::string> seen;
    std::vector<std::string> unseen;
    for (auto& r : rpdos_) {
      if (r.seen) {
        r.told = true;
        r.silent = false;
        told_any_ = true;
        seen.push_back(def(r).name);
      } else {
        keep_silent(r, def(r).name + " was not seen on the bus before the takeover");
        unseen.push_back(def(r).name);
      }
    }
    clear_momentary();
    std::string note = "adopted at a takeover: ";
    note += seen.empty() ? "no RPDO seen on the bus" : fmt::format("{} as last on the bus", fmt::join(seen, ", "));
    if (!unseen.empty()) note += fmt::format("; {} not seen: kept silent", fmt::join(unseen, ", "));
    spdlog::info("{}: {}", ctx_.device.name, note);
    ctx_.node.note_set_values_at_start(note);
    keep();
    for (auto& r : rpdos_) {
      if (!r.silent) r.transmitter->resend();
    }
    if (changed_) changed_();
  }

  void keep_silent(Rpdo& r, const std::string& why) {
    r.silent = true;
    r.silent_why = why;
  }

  // A running device's RPDO as it holds it; if it cannot be read, the kept values, else silence.
  void start_read_back(std::size_t k, const std::string& note, const std::vector<std::uint8_t>& base) {
    const auto gen = start_generation_;
    const bool partly = !base.empty();
    read_back_rpdo(*ctx_.sdo, ctx_.device.node_id, mapping(rpdos_[k]), readable_entries(rpdos_[k]), base,
                   [this, gen, k, note, partly](Result<std::vector<std::uint8_t>> got) {
                     // Off the loop thread only while the bridge shuts down (its SDO client completes what waits).
                     if (!ctx_.loop.on_loop_thread() || gen != start_generation_) return;
                     auto& r = rpdos_[k];
                     if (!r.silent) return;  // an operator wrote it meanwhile: theirs stands
                     const auto& name = def(r).name;
                     std::string result;
                     if (got) {
                       static_cast<void>(codec_.receive(r.pdo, *got));
                       r.silent = false;
                       result = name + (partly ? " read back from the device (its write-only objects restored)"
                                               : " read back from the device");
                     } else if (auto kept = kept_payload(r)) {
                       static_cast<void>(codec_.receive(r.pdo, *kept));
                       r.silent = false;
                       result = fmt::format("{} not read back ({}): restored", name, got.error().message);
                     } else {
                       keep_silent(r, fmt::format("{} not read back ({}) and not restored ({})", name,
                                                  got.error().message, kept.error().message));
                       result = r.silent_why +
                                ": kept silent, the device keeps what it last received until an operator sets it";
                     }
                     clear_momentary();
                     if (r.silent)
                       spdlog::warn("{}: {}", ctx_.device.name, result);
                     else
                       spdlog::info("{}: {}", ctx_.device.name, result);
                     auto updated = ctx_.node.set_values_at_start();
                     ctx_.node.note_set_values_at_start((updated.empty() ? note : updated) + "; " + result);
                     r.transmitter->resend();
                     after_change();
                   });
  }

  // The RPDO carries a stopping command being pressed now, to a device that is heard.
  bool stopping(std::size_t k) const {
    return stop_pulses_ > 0 && carries_control_word(rpdos_[k]) && ctx_.node.heard();
  }

  bool may_send(std::size_t k) const {
    const auto& r = rpdos_[k];
    if (!r.valid_on_device || r.silent) return false;
    if (options_.silent_until_told && !told_any_) return false;
    // A stop being pressed goes on for as long as it must be held, whatever is believed meanwhile
    // (another master's SYNCs, a boot-up being judged): the device is heard.
    if (stopping(k)) return true;
    if (ctx_.loop.transmission_held()) return false;  // another master's bus: only stops, at once
    // A boot-up is being judged: the device may have just rebooted (it takes no PDO until it is
    // started again, and must get nothing that enables then) or the frame was spoofed (it keeps
    // what it last received for one heartbeat period). Held back, not refused; stops go all the same.
    if (ctx_.node.boot_up_pending()) return false;
    if (stop_pulses_ > 0 && ctx_.node.heard()) return true;
    if (ctx_.node.ready_for_pdos()) return true;
    // An operator's stop for a device the bridge does not control just now: its RPDOs go out while
    // it is heard and carry nothing that enables (never by themselves: a restarted bridge whose
    // boot fails must not stop a running line unasked).
    return stop_mode_ && ctx_.node.heard() && !carries_enabling();
  }

  // Why may_send(k) is false, for whoever waits for the frame.
  std::string why_not(std::size_t k) const {
    const auto& name = ctx_.device.name;
    const auto& node = ctx_.node;
    const auto& r = rpdos_[k];
    if (!r.valid_on_device) return fmt::format("{} has {} disabled (COB-ID bit 31)", name, def(r).name);
    if (r.silent) return name + ": " + r.silent_why;
    if (ctx_.loop.transmission_held()) return ctx_.another_master("the frame held back");
    if (node.boot_up_pending()) return name + " sent a boot-up that is being judged: its RPDOs wait";
    if (options_.silent_until_told && !told_any_)
      return name + ": its RPDOs stay silent until an operator's first change";
    if (!node.online()) return name + " is offline (no heartbeat)";
    if (!node.configured()) {
      return name + " has not passed its boot (its state became unknown, or the boot failed): while it is heard it "
                    "takes only stops (program off, extruder stopped, a stopping command)";
    }
    if (node.commanded_state() != canopen::NmtState::operational) return name + " was told to leave operational (NMT)";
    if (node.state() != canopen::NmtState::operational) {
      return fmt::format("{} reports {}, not operational", name, canopen::to_string(node.state()));
    }
    return name + ": the gateway does not send this PDO yet";
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
  Options options_;
  std::function<void()> changed_;
  std::vector<Rpdo> rpdos_;
  std::optional<MomentaryCommands> pulses_;
  bool persist_ = false;
  bool started_once_ = false;  // a start has decided the image
  bool told_any_ = false;      // an operator changed the image in this run
  bool stop_mode_ = false;     // an operator's stop for a device the bridge does not control just now
  bool quiet_ = false;         // a press sends its own first frame
  // A standby before its first start: the master's RPDO frames on the bus write the image.
  bool observing_ = ctx_.bus.role == profiles::BusRole::standby;
  unsigned stop_pulses_ = 0;  // stopping commands being pressed now
  std::uint64_t start_generation_ = 0;
  std::array<std::uint32_t, 4> identity_{};  // 1018h of the device as its last boot read it
};

}  // namespace lb::gateways
