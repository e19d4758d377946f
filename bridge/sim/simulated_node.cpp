#include "sim/simulated_node.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "canopen/sdo_abort.hpp"
#include "sim/device_dictionary.hpp"
#include "sim/little_endian.hpp"

namespace lb::sim {

using canopen::NmtState;
using Reset = NmtSlave::Reset;

namespace {

constexpr double kMaxStep = 0.1;  // s: a stalled loop must not make the simulation jump
constexpr auto kShortRpdoEmcyGap = std::chrono::seconds(1);
constexpr std::uint16_t kEmcyPdoLength = 0x8210;  // PDO not processed due to length error

constexpr std::uint16_t kHeartbeatError = 0x8130;  // CiA 301: life guard or heartbeat error

canopen::ObjectDictionary::Bytes bytes_of(std::uint64_t raw, std::size_t size) {
  canopen::ObjectDictionary::Bytes out(size);
  for (std::size_t i = 0; i < size; ++i) out[i] = static_cast<std::uint8_t>(raw >> (8 * i));
  return out;
}

bool is_string(canopen::DataType type) {
  return type == canopen::DataType::visible_string || type == canopen::DataType::octet_string;
}

}  // namespace

SimulatedNode::SimulatedNode(canopen::BusLoop& loop, const profiles::DeviceConfig& device,
                             const profiles::Profile& profile, Application application)
    : loop_(loop),
      device_(device),
      profile_(profile),
      app_(std::move(application)),
      nmt_(loop, device.node_id,
           {[this](Reset kind) { on_reset(kind); }, [this](NmtState from, NmtState to) { on_state(from, to); }}),
      sdo_(loop, device.node_id, make_device_dictionary(device, profile)),
      pdos_(loop, device, profile, image_, sdo_.dictionary(),
            {[this] { return nmt_.state() == NmtState::operational; },
             [this](std::span<const canopen::PdoEntry> mapped) {
               if (app_.received) app_.received(mapped);
             },
             [this](const profiles::PdoDef& pdo, std::size_t length, std::size_t needed) {
               on_short_rpdo(pdo, length, needed);
             }},
            app_.event_tpdos),
      consumer_(
          loop, sdo_.dictionary(),
          [this] {
            raise_error(kHeartbeatError);
            nmt_.communication_error();
          },
          [this] { clear_error(kHeartbeatError); }) {
  // No SDO answer at all in NMT stopped (CiA 301), nor while a reset takes its time
  // (simulation.reset_time_ms): a master's request times out.
  sdo_.set_gate([this] { return nmt_.state() != NmtState::stopped && !nmt_.resetting(); });
  link_image_objects();
  link_communication_objects();
  link_error_objects();
  listen_for_sync(canopen::cob::sync);
}

// A handler per identifier ever used for SYNC (the loop keeps handlers for its life): only the
// one 1005h names now counts.
void SimulatedNode::listen_for_sync(std::uint32_t id) {
  if (!sync_ids_.insert(id).second) return;
  loop_.on_frame(id, [this, id](const can::CanFrame&) {
    if (id == sync_id_) on_sync();
  });
}

void SimulatedNode::link_image_objects() {
  auto& od = sdo_.dictionary();
  for (const auto& o : profile_.objects) {
    if (!is_string(o.type)) serve_from_image(o.index, o.sub, image_.slot(o.index, o.sub));
  }
  for (const std::uint16_t index : {kSecondStatusWord, kSecondControlWord}) {
    if (od.find(index, 0) != nullptr) serve_from_image(index, 0, image_.slot(index, 0));
  }
  if (od.find(kSecondStatusWord, 0) != nullptr) second_status_word_ = image_.find(kSecondStatusWord, 0);
}

void SimulatedNode::serve_from_image(std::uint16_t index, std::uint8_t sub, std::size_t slot) {
  image_slots_.push_back(slot);
  auto& od = sdo_.dictionary();
  const auto* entry = od.find(index, sub);
  if (entry == nullptr) throw std::runtime_error(device_.name + ": no dictionary entry for an image object");
  const std::size_t size = canopen::bit_size(entry->type) / 8;
  (void)od.set_on_read(index, sub, [this, slot, size] { return bytes_of(image_.get(slot), size); });
  (void)od.set_on_write(index, sub, [this, slot](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    image_.set(slot, little_endian(v));
    pdos_.data_changed();
    return std::nullopt;
  });
}

void SimulatedNode::link_communication_objects() {
  auto& od = sdo_.dictionary();
  (void)od.set_on_read(0x1001, 0, [this] { return canopen::ObjectDictionary::Bytes{error_register_}; });
  (void)od.set_on_read(0x1017, 0,
                       [this] { return bytes_of(static_cast<std::uint64_t>(heartbeat_period_.count()), 2); });
  // 1005h COB-ID SYNC (CiA 301: rw). This device consumes SYNC only: bit 30 (it would produce it)
  // and bit 29 (a 29-bit identifier) are refused; bits 0..10 name the identifier it listens to.
  (void)od.set_on_read(0x1005, 0, [this] { return bytes_of(sync_id_, 4); });
  (void)od.set_on_write(0x1005, 0, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    const auto value = little_endian(v);
    if ((value & 0x6000'0000U) != 0 || (value & 0x1FFF'F800U) != 0) return canopen::sdo_abort::value_range_exceeded;
    sync_id_ = static_cast<std::uint32_t>(value & 0x7FF);
    listen_for_sync(sync_id_);
    return std::nullopt;
  });
  (void)od.set_on_write(0x1017, 0, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    heartbeat_period_ = std::chrono::milliseconds(little_endian(v));
    nmt_.set_heartbeat_period(heartbeat_period_);
    return std::nullopt;
  });
  (void)od.set_on_write(kSimulationControl, 0, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    const auto command = little_endian(v);
    if (command != 1 && command != 2) return canopen::sdo_abort::value_range_exceeded;
    const Reset kind = command == 1 ? Reset::node : Reset::communication;
    // After this write's confirmation went out: a posted task runs after the current frame.
    loop_.post([this, kind] {
      spdlog::info("sim {}: simulation control: reset {} without boot-up message", device_.name,
                   kind == Reset::node ? "node" : "communication");
      nmt_.reset(kind, false);
    });
    return std::nullopt;
  });
}

void SimulatedNode::boot() {
  nmt_.announce_nmt_resets(device_.simulation.boot_up_after_nmt_reset);
  nmt_.set_reset_time(device_.simulation.reset_time);
  // The faults name any object, the application's too: they exist by now.
  for (const auto key : device_.simulation.ignore_writes) {
    const auto index = static_cast<std::uint16_t>(key >> 8);
    const auto sub = static_cast<std::uint8_t>(key);
    if (auto r = sdo_.dictionary().ignore_writes(index, sub); !r) {
      throw std::runtime_error(device_.name + ": simulation ignore_writes: " + r.error().message);
    }
    spdlog::info("sim {}: SDO writes of {:04X}h sub {} are confirmed and ignored (simulation ignore_writes)",
                 device_.name, index, sub);
  }
  spdlog::info("sim {}: {} node {} powered on ({})", device_.name, profile_.device, device_.node_id, profile_.key());
  nmt_.reset(Reset::node);
}

void SimulatedNode::on_reset(Reset kind) {
  if (kind == Reset::node) {
    for (const std::size_t s : image_slots_) image_.set(s, 0);
    // ARRAY objects: sub 0 tells how many elements the device has (all the profile allows).
    for (const auto& o : profile_.objects) {
      if (o.sub == 0) continue;
      const std::size_t count = image_.find(o.index, 0);
      if (count != canopen::ProcessImage::npos) image_.set(count, std::max<std::uint64_t>(image_.get(count), o.sub));
    }
    error_register_ = 0;
    active_errors_.clear();
    error_history_.clear();  // kept in RAM: a power-on value, as CANopenNode's
    auto& od = sdo_.dictionary();
    (void)od.set(kDeviceText, 0, {});
    for (const auto index : commands_)
      (void)od.set(index, 0, canopen::ObjectDictionary::Bytes(od.find(index, 0)->value.size()));
    if (app_.reset) app_.reset();
  }
  pdos_.reset();
  sdo_.reset();
  consumer_.reset();
  sync_id_ = canopen::cob::sync;  // a communication object: back to its power-on value
  heartbeat_period_ = device_.simulation.heartbeat_period;
  nmt_.set_heartbeat_period(heartbeat_period_);
  last_sync_.reset();
  spdlog::debug("sim {}: reset {}: power-on values restored", device_.name,
                kind == Reset::node ? "node" : "communication");
}

void SimulatedNode::on_state(NmtState from, NmtState to) {
  if (from == NmtState::operational) pdos_.left_operational();
  if (to == NmtState::operational) pdos_.started();
  spdlog::debug("sim {}: NMT {} -> {}", device_.name, canopen::to_string(from), canopen::to_string(to));
}

std::size_t SimulatedNode::slot(std::string_view object) const {
  const auto* def = profile_.object(object);
  const std::size_t s = def != nullptr ? image_.find(def->index, def->sub) : canopen::ProcessImage::npos;
  if (s == canopen::ProcessImage::npos)
    throw std::runtime_error(device_.name + ": profile has no object " + std::string(object));
  return s;
}

std::optional<unsigned> SimulatedNode::bit(std::string_view set, std::string_view name) const {
  const auto* s = profile_.bitset(set);
  return s != nullptr ? s->bit(name) : std::nullopt;
}

std::uint64_t SimulatedNode::get(std::uint16_t index, std::uint8_t sub) const {
  const std::size_t s = image_.find(index, sub);
  return s == canopen::ProcessImage::npos ? 0 : image_.get(s);
}

void SimulatedNode::set(std::uint16_t index, std::uint8_t sub, std::uint64_t raw) {
  const std::size_t s = image_.find(index, sub);
  if (s != canopen::ProcessImage::npos) image_.set(s, raw);
}

std::size_t SimulatedNode::add_object(std::uint16_t index, canopen::DataType type, canopen::ObjectAccess access,
                                      std::optional<std::int64_t> min, std::optional<std::int64_t> max) {
  if (auto r = sdo_.dictionary().add(index, 0, type, access, {}, min, max); !r) {
    throw std::runtime_error(device_.name + ": " + r.error().message);
  }
  const std::size_t s = image_.slot(index, 0);
  serve_from_image(index, 0, s);
  return s;
}

void SimulatedNode::check_writes(std::uint16_t index, std::uint8_t sub, canopen::ObjectDictionary::WriteHook check) {
  const std::size_t s = image_.find(index, sub);
  if (s == canopen::ProcessImage::npos) {
    throw std::runtime_error(device_.name + ": a write check for an object outside the image");
  }
  (void)sdo_.dictionary().set_on_write(index, sub,
                                       [this, s, check = std::move(check)](std::span<const std::uint8_t> v) {
                                         if (auto code = check(v)) return code;
                                         image_.set(s, little_endian(v));
                                         pdos_.data_changed();
                                         return std::optional<std::uint32_t>{};
                                       });
}

void SimulatedNode::add_command(std::uint16_t index, canopen::DataType type,
                                canopen::ObjectDictionary::WriteHook hook) {
  auto& od = sdo_.dictionary();
  if (auto r = od.add(index, 0, type, canopen::ObjectAccess::rw); !r)
    throw std::runtime_error(device_.name + ": " + r.error().message);
  (void)od.set_on_write(index, 0, std::move(hook));
  commands_.push_back(index);
}

void SimulatedNode::send_emergency(std::uint16_t code, std::uint8_t error_register,
                                   std::array<std::uint8_t, 5> manufacturer) {
  error_register_ = error_register;
  // CiA 301 1003h: every EMCY goes into the history, newest at sub 1, the oldest falls off the end.
  error_history_.insert(error_history_.begin(), code);
  if (error_history_.size() > kErrorFieldEntries) error_history_.resize(kErrorFieldEntries);
  can::CanFrame f;
  f.id = canopen::cob::emcy_base + device_.node_id;  // 1014h
  f.len = 8;
  f.data = {static_cast<std::uint8_t>(code),
            static_cast<std::uint8_t>(code >> 8),
            error_register,
            manufacturer[0],
            manufacturer[1],
            manufacturer[2],
            manufacturer[3],
            manufacturer[4]};
  (void)loop_.send(f);
}

void SimulatedNode::link_error_objects() {
  auto& od = sdo_.dictionary();
  (void)od.set_on_write(kErrorSimulation, 0, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    const auto value = little_endian(v);
    const auto code = static_cast<std::uint16_t>(value & 0xFFFF);
    const bool clear = (value & 0x8000'0000U) != 0;
    if (!clear && code == 0) return canopen::sdo_abort::value_range_exceeded;
    // After this write's confirmation went out.
    loop_.post([this, code, clear] {
      if (!clear) return raise_error(code);
      if (code != 0) return clear_error(code);
      active_errors_.clear();
      spdlog::info("sim {}: every error cleared (error simulation)", device_.name);
      send_emergency(0x0000, 0, {});
    });
    return std::nullopt;
  });
  if (od.find(kErrorField, 0) == nullptr) return;
  (void)od.set_on_read(kErrorField, 0, [this] {
    return canopen::ObjectDictionary::Bytes{static_cast<std::uint8_t>(error_history_.size())};
  });
  // CiA 301: writing 0 deletes the history; it does not reset the errors, which stay active (1001h
  // unchanged, no EMCY). Any other value is refused.
  (void)od.set_on_write(kErrorField, 0, [this](std::span<const std::uint8_t> v) -> std::optional<std::uint32_t> {
    if (little_endian(v) != 0) return canopen::sdo_abort::value_range_exceeded;
    error_history_.clear();
    spdlog::info("sim {}: error history 1003h cleared", device_.name);
    return std::nullopt;
  });
  for (std::uint8_t sub = 1; sub <= kErrorFieldEntries; ++sub) {
    (void)od.set_on_read(kErrorField, sub, [this, sub] {
      // Beyond the count there is nothing recorded: 0, as the entry's power-on value.
      return bytes_of(sub <= error_history_.size() ? error_history_[sub - 1] : 0, 4);
    });
  }
}

std::uint8_t SimulatedNode::register_of_active() const {
  std::uint8_t reg = 0;
  for (const auto code : active_errors_) {
    reg |= 0x01;  // generic: any error
    switch (code >> 12) {
      case 0x2: reg |= 0x02; break;  // current
      case 0x3: reg |= 0x04; break;  // voltage
      case 0x4: reg |= 0x08; break;  // temperature
      case 0x8: reg |= 0x10; break;  // communication
      default: break;
    }
  }
  return reg;
}

void SimulatedNode::raise_error(std::uint16_t code, std::array<std::uint8_t, 5> manufacturer) {
  if (std::find(active_errors_.begin(), active_errors_.end(), code) == active_errors_.end())
    active_errors_.push_back(code);
  spdlog::info("sim {}: error {:04X}h active ({} active)", device_.name, code, active_errors_.size());
  send_emergency(code, register_of_active(), manufacturer);
}

void SimulatedNode::clear_error(std::uint16_t code, std::optional<std::array<std::uint8_t, 5>> last_word) {
  const auto it = std::find(active_errors_.begin(), active_errors_.end(), code);
  if (it == active_errors_.end()) return;
  active_errors_.erase(it);
  const auto reg = register_of_active();
  spdlog::info("sim {}: error {:04X}h cleared: EMCY 0000h with error register {:02X}h ({} still active)", device_.name,
               code, reg, active_errors_.size());
  if (last_word) send_emergency(code, reg, *last_word);
  send_emergency(0x0000, reg, {});
}

void SimulatedNode::on_sync() {
  const auto now = std::chrono::steady_clock::now();
  const double dt = last_sync_ ? std::min(std::chrono::duration<double>(now - *last_sync_).count(), kMaxStep) : 0.0;
  last_sync_ = now;
  if (nmt_.state() != NmtState::operational) return;
  pdos_.apply_pending();
  if (app_.step) app_.step(dt);
  if (second_status_word_) image_.set(*second_status_word_, (image_.get(*second_status_word_) + 1) & 0xFFFF);
  pdos_.on_sync();
}

void SimulatedNode::on_short_rpdo(const profiles::PdoDef& pdo, std::size_t length, std::size_t needed) {
  ++short_rpdos_;
  const auto now = std::chrono::steady_clock::now();
  if (last_short_emcy_ && now - *last_short_emcy_ < kShortRpdoEmcyGap) return;
  last_short_emcy_ = now;
  spdlog::warn("sim {}: {} with {} bytes not applied, its mapping needs {} ({} so far): EMCY 8210h", device_.name,
               pdo.name, length, needed, short_rpdos_);
  send_emergency(kEmcyPdoLength, error_register_,
                 {static_cast<std::uint8_t>(pdo.number()), static_cast<std::uint8_t>(length),
                  static_cast<std::uint8_t>(needed), 0, 0});
}

}  // namespace lb::sim
