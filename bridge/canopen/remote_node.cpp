#include "canopen/remote_node.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace lb::canopen {

namespace {

NmtState state_after(NmtCommand cmd) {
  switch (cmd) {
    case NmtCommand::start: return NmtState::operational;
    case NmtCommand::stop: return NmtState::stopped;
    case NmtCommand::enter_pre_operational: return NmtState::pre_operational;
    case NmtCommand::reset_node:
    case NmtCommand::reset_communication: break;
  }
  return NmtState::unknown;  // a reset: the boot-up tells
}

}  // namespace

std::string_view to_string(NodeEvent event) {
  switch (event) {
    case NodeEvent::boot_up: return "boot-up";
    case NodeEvent::lost: return "heartbeat lost";
    case NodeEvent::returned: return "heartbeat (back)";
    case NodeEvent::unexpected_state: return "state not commanded";
  }
  return "?";
}

RemoteNode::RemoteNode(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds heartbeat_timeout,
                       bool may_transmit)
    : loop_(loop),
      may_transmit_(may_transmit),
      heartbeat_timeout_(heartbeat_timeout),
      heartbeat_(loop, node_id, heartbeat_timeout,
                 HeartbeatConsumer::Listener{
                     .on_boot_up = [this] { boot_up_seen(); },
                     .on_change = [this](NmtState s, bool o) { changed(s, o); },
                     .on_heartbeat = [this](NmtState s) { heartbeat(s); },
                     .on_malformed =
                         [this](const can::CanFrame& f) {
                           ++stats_.malformed_heartbeats;
                           if (malformed_log_.allow()) {
                             spdlog::warn("{}: node {}: heartbeat with {} bytes ignored (CiA 301: 1){}",
                                          loop_.bus().uri(), this->node_id(), f.len, held_back_note(malformed_log_));
                           }
                         },
                 }) {
  loop_.on_frame(cob::emcy_base + node_id, [this](const can::CanFrame& f) {
    heard_frame(f.timestamp_ns);
    on_emcy_frame(f);
  });
  // Its heartbeats (the consumer's own handler judges them) and its SDO answers are its own too.
  loop_.on_frame(cob::heartbeat_base + node_id, [this](const can::CanFrame& f) { heard_frame(f.timestamp_ns); });
  loop_.on_frame(cob::sdo_tx_base + node_id, [this](const can::CanFrame& f) { heard_frame(f.timestamp_ns); });
}

bool RemoteNode::heard() const {
  if (last_heard_ns_ == 0) return false;
  const auto now =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
  return now - last_heard_ns_ <= std::chrono::nanoseconds(heartbeat_timeout_).count();
}

Result<void> RemoteNode::command(NmtCommand cmd) {
  if (!may_transmit_) return make_error("the bus is in the monitor role: the bridge sends no NMT commands there");
  // A stop (stopped, pre-operational) goes out whatever another master's presence holds back.
  const bool stops = cmd == NmtCommand::stop || cmd == NmtCommand::enter_pre_operational;
  const auto frame = make_nmt_command(cmd, node_id());
  if (auto r = stops ? loop_.send_stop(frame) : loop_.send(frame); !r) return r;
  commanded_ = state_after(cmd);
  if (cmd == NmtCommand::reset_node || cmd == NmtCommand::reset_communication) configured_ = false;
  confirmed_ = false;
  commanded_at_ = std::chrono::steady_clock::now();
  for (auto* d : drivers_) d->on_command(cmd);
  return {};
}

Result<void> RemoteNode::use_pdos(std::span<const PdoInUse> pdos) {
  for (auto* d : drivers_) {
    if (auto r = d->on_config(pdos); !r) return r;
  }
  pdos_.assign(pdos.begin(), pdos.end());
  return {};
}

// A boot-up is believed once the state that follows agrees: a device that has just booted is
// pre-operational (or stopped, or silent: its heartbeat producer may be off at power-on), never
// operational unless it starts itself. So a spoofed 70Xh#00 (or a device that sends one by
// fault) next to a running device changes nothing: its configuration and set values stay, it is
// not booted again, and a few such frames cannot make a boot-up storm that locks it out.
void RemoteNode::boot_up_seen() {
  ++stats_.boot_ups;
  if (!may_transmit_ || believe_every_boot_up_) return booted();
  boot_up_pending_ = true;
}

void RemoteNode::booted() {
  boot_up_pending_ = false;
  configured_ = false;
  commanded_ = NmtState::unknown;
  spdlog::info("{}: node {} booted (boot-up #{})", loop_.bus().uri(), node_id(), stats_.boot_ups);
  // CiA 301: a device starts without active errors; what it reported before is gone.
  update_errors([](ActiveErrors& e) { e.reset_by_boot_up(); });
  emit(Event::boot_up);
}

void RemoteNode::changed(NmtState state, bool online) {
  const bool came_online = online && !was_online_;
  const bool went_offline = !online && was_online_;
  was_online_ = online;
  for (auto* d : drivers_) d->on_nmt_change(state, online);
  if (went_offline) {
    if (boot_up_pending_) booted();  // a boot-up and then silence: a device whose heartbeat is off at power-on
    configured_ = false;
    emit(Event::lost);
  } else if (came_online) {
    emit(Event::returned);
  }
}

// A device told to be operational that reports pre-operational or stopped may have been reset
// without its boot-up reaching the master: its configuration may be gone. The state reported
// right after a command may predate it, so a difference counts once a heartbeat has confirmed the
// command, or once a whole heartbeat timeout has passed without.
void RemoteNode::heartbeat(NmtState state) {
  check_state(state);
  if (state == NmtState::boot_up) return;
  for (auto* d : drivers_) d->on_heartbeat(state);
}

void RemoteNode::check_state(NmtState state) {
  if (boot_up_pending_ && state != NmtState::boot_up) {
    if (state != NmtState::operational) {
      booted();
    } else {
      boot_up_pending_ = false;
      ++stats_.boot_ups_not_believed;
      if (spoof_log_.allow()) {
        spdlog::warn("{}: node {}: a boot-up, then a heartbeat saying operational: not believed (a spoofed frame or a "
                     "device fault; {} so far); its configuration and set values stay{}",
                     loop_.bus().uri(), node_id(), stats_.boot_ups_not_believed, held_back_note(spoof_log_));
      }
    }
  }
  if (commanded_ == NmtState::unknown || state == NmtState::boot_up) return;
  if (state == commanded_) {
    confirmed_ = true;
    return;
  }
  if (!confirmed_ && std::chrono::steady_clock::now() - commanded_at_ < heartbeat_timeout_) return;
  spdlog::warn("{}: node {} reports {} but was told to be {}: its configuration may be gone", loop_.bus().uri(),
               node_id(), to_string(state), to_string(commanded_));
  configured_ = false;
  commanded_ = NmtState::unknown;
  emit(Event::unexpected_state);
}

void RemoteNode::emit(Event event) {
  if (!may_transmit_) return;  // a monitor only watches
  for (auto* d : drivers_) d->on_event(event);
}

void RemoteNode::on_emcy_frame(const can::CanFrame& frame) {
  const auto e = parse_emergency(frame);
  if (!e) {
    ++stats_.malformed_emergencies;
    if (malformed_log_.allow()) {
      spdlog::warn("{}: node {}: EMCY with {} bytes ignored (CiA 301: 8){}", loop_.bus().uri(), node_id(), frame.len,
                   held_back_note(malformed_log_));
    }
    return;
  }
  ++stats_.emergencies;
  errors_.apply(*e);
  if (emcy_log_.allow()) {
    spdlog::log(e->is_reset() ? spdlog::level::info : spdlog::level::warn,
                "{}: node {} EMCY {:04X}h ({}), register {:02X}h{}", loop_.bus().uri(), node_id(), e->error_code,
                emcy_family(e->error_code), e->error_register, held_back_note(emcy_log_));
  }
  for (auto* d : drivers_) d->on_emcy(*e);
}

}  // namespace lb::canopen
