#include "canopen/remote_node.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
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
                     .on_heartbeat = [this](NmtState s, bool came_online) { heartbeat(s, came_online); },
                     .on_missing = [this] { return missing(); },
                     .on_offline = [this] { went_offline(); },
                     .on_malformed =
                         [this](const can::CanFrame& f) {
                           ++stats_.malformed_heartbeats;
                           if (malformed_log_.allow()) {
                             spdlog::warn("{}: node {}: heartbeat with {} bytes ignored (CiA 301: 1){}",
                                          loop_.bus().uri(), this->node_id(), f.len, held_back_note(malformed_log_));
                           }
                         },
                 }) {
  where_.node = node_id;
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

std::chrono::nanoseconds RemoteNode::evidence_period() const {
  if (producer_period_ && producer_period_->count() > 0) return *producer_period_;
  return heartbeat_timeout_ / 2;
}

Result<void> RemoteNode::command(NmtCommand cmd) {
  if (!may_transmit_) return make_error("the bus is in the monitor role: the bridge sends no NMT commands there");
  // A stop (stopped, pre-operational) goes out whatever another master's presence holds back.
  const bool stops = cmd == NmtCommand::stop || cmd == NmtCommand::enter_pre_operational;
  const auto frame = make_nmt_command(cmd, node_id());
  if (auto r = stops ? loop_.send_stop(frame) : loop_.send(frame); !r) return r;
  commanded_ = state_after(cmd);
  // What it reports next follows this command, not its boot-up: the boot-up stands (a boot under
  // way may have started the device while it rebooted, and then it runs on power-on values).
  if (boot_up_pending_) boot_up_then_commanded_ = true;
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

// Every frame on 700h + node-ID with a state byte. What changes is believed on evidence (the top
// of remote_node.hpp); the drivers hear of a believed change (on_nmt_change) before the event it
// makes (returned, boot-up, a state not commanded), as before the master acts on it.
void RemoteNode::heartbeat(NmtState state, bool came_online) {
  if (missing_) {
    missing_ = false;
    checking_ = false;
    spdlog::info("{}: node {}: its heartbeat is back", loop_.bus().uri(), node_id());
  }
  if (came_online) {
    journal::log(journal::Event::device_online, spdlog::level::info, where_,
                 fmt::format("{}: node {} online ({})", loop_.bus().uri(), node_id(), to_string(state)),
                 {{journal::kNmtState, std::string(to_string(state))}});
  }
  if (state == NmtState::boot_up) return boot_up_seen(came_online);
  const NmtState before = believed_;
  const auto judged = judge(state, came_online);
  believed_ = judged.believed;
  const bool boot_up_believed = judged.boot_up;
  if (believed_ != before || came_online) {
    for (auto* d : drivers_) d->on_nmt_change(believed_, true);
  }
  if (came_online) emit(Event::returned);
  if (boot_up_believed) booted(state);
  if (state == believed_ && !boot_up_pending_) check_commanded(state);
  for (auto* d : drivers_) d->on_heartbeat(state);
}

RemoteNode::Judgement RemoteNode::judge(NmtState state, bool came_online) {
  // Nothing to contradict: its first heartbeat, a monitor's view, the first state after a
  // believed boot-up.
  if (came_online || !may_transmit_ || (believed_ == NmtState::boot_up && !boot_up_pending_)) {
    candidate_.reset();
    return {state};
  }
  const std::int64_t ts = heartbeat_.last_heartbeat_ns();
  if (boot_up_pending_) return judge_boot_up(state, ts);
  if (state == believed_) {
    if (candidate_) not_believed(*candidate_, state);
    return {state};
  }
  // It does what it was told: the transition the master expects, believed at once.
  if ((commanded_ != NmtState::unknown && state == commanded_) || evidence(state, ts)) {
    candidate_.reset();
    return {state};
  }
  return {believed_};
}

// A device that has just booted is pre-operational (or stopped), never operational unless it
// starts itself: "operational" right after a boot-up is the running device's own heartbeat next
// to a spoofed (or faulty) boot-up message. Unless the master itself commanded it after the
// boot-up (a boot under way started it): then the boot-up stands.
RemoteNode::Judgement RemoteNode::judge_boot_up(NmtState state, std::int64_t timestamp_ns) {
  if (boot_up_then_commanded_) return {state, true};
  if (state != NmtState::operational) {
    // The boot-up message opens the evidence: a state reported since, a producer period after it.
    if (!candidate_) candidate_ = Candidate{state, boot_up_ns_};
    return evidence(state, timestamp_ns) ? Judgement{state, true} : Judgement{believed_};
  }
  boot_up_pending_ = false;
  boot_up_then_commanded_ = false;
  candidate_.reset();
  ++stats_.boot_ups_not_believed;
  if (spoof_log_.allow()) {
    spdlog::warn("{}: node {}: a boot-up, then a heartbeat saying operational: not believed (a spoofed frame or a "
                 "device fault; {} so far); its configuration and set values stay{}",
                 loop_.bus().uri(), node_id(), stats_.boot_ups_not_believed, held_back_note(spoof_log_));
  }
  return {believed_ == NmtState::boot_up ? state : believed_};
}

// A boot-up message is believed once the state that follows is reported consistently (or the
// device falls silent: its heartbeat producer may be off at power-on). So a spoofed 70Xh#00 (or a
// device that sends one by fault) next to a running device changes nothing: its configuration
// and set values stay, it is not booted again, and a few such frames cannot make a boot-up storm
// that locks it out.
void RemoteNode::boot_up_seen(bool came_online) {
  ++stats_.boot_ups;
  candidate_.reset();
  boot_up_ns_ = heartbeat_.last_heartbeat_ns();
  const NmtState before = believed_;
  const bool at_once = !may_transmit_ || believe_every_boot_up_;
  if (came_online || at_once) believed_ = NmtState::boot_up;
  if (!at_once) {
    boot_up_pending_ = true;
    boot_up_then_commanded_ = false;
  }
  if (believed_ != before || came_online) {
    for (auto* d : drivers_) d->on_nmt_change(believed_, true);
  }
  if (at_once) booted(NmtState::boot_up);
  if (came_online) emit(Event::returned);
}

// One more heartbeat of a state not believed yet: true once it was reported over a producer
// period with nothing else in between.
bool RemoteNode::evidence(NmtState state, std::int64_t timestamp_ns) {
  if (!candidate_ || candidate_->state != state) {
    if (candidate_ && !boot_up_pending_) not_believed(*candidate_, state);
    candidate_ = Candidate{state, timestamp_ns};
    return false;
  }
  if (timestamp_ns - candidate_->since_ns < evidence_period().count()) return false;
  candidate_.reset();
  return true;
}

void RemoteNode::not_believed(const Candidate& candidate, NmtState contradicted_by) {
  candidate_.reset();
  ++stats_.states_not_believed;
  if (spoof_log_.allow()) {
    spdlog::warn("{}: node {}: a heartbeat saying {}, then one saying {}: not believed (a spoofed frame or a device "
                 "fault; {} so far); it is still taken for {}{}",
                 loop_.bus().uri(), node_id(), to_string(candidate.state), to_string(contradicted_by),
                 stats_.states_not_believed, to_string(believed_), held_back_note(spoof_log_));
  }
}

void RemoteNode::booted(NmtState state) {
  boot_up_pending_ = false;
  boot_up_then_commanded_ = false;
  candidate_.reset();
  believed_ = state;
  configured_ = false;
  commanded_ = NmtState::unknown;
  spdlog::info("{}: node {} booted (boot-up #{})", loop_.bus().uri(), node_id(), stats_.boot_ups);
  // CiA 301: a device starts without active errors; what it reported before is gone.
  update_errors([](ActiveErrors& e) { e.reset_by_boot_up(); });
  emit(Event::boot_up);
}

// The heartbeat consumer found no heartbeat within the timeout (on the bus's time). A device
// still heard by other frames of its own since its last heartbeat is alive: its heartbeat
// producer may have been changed (1017h), which the check registered by its master looks at.
bool RemoteNode::missing() {
  const auto now = std::chrono::steady_clock::now();
  if (!missing_) {
    // Heard after its next heartbeat was due: it runs, but its heartbeat stopped. A device that
    // died between two heartbeats sent nothing after that.
    const auto due = heartbeat_.last_heartbeat_ns() + evidence_period().count();
    const bool heard_since = last_heard_ns_ > due && heard();
    if (!may_transmit_ || !heartbeat_check_ || !configured_ || !heard_since) return true;
    missing_ = true;
    checking_ = true;
    missing_since_ = now;
    ++stats_.heartbeats_missing_while_heard;
    spdlog::warn("{}: node {}: no heartbeat for {} ms, but it is heard (TPDO, EMCY or SDO answer): not lost; its "
                 "heartbeat producer time 1017h is checked",
                 loop_.bus().uri(), node_id(), heartbeat_timeout_.count());
    heartbeat_.keep_waiting();
    heartbeat_check_();
    return false;
  }
  if (checking_ && heard() && now - missing_since_ < kHeartbeatCheckBound) {
    heartbeat_.keep_waiting();
    return false;
  }
  missing_ = false;
  checking_ = false;
  return true;
}

void RemoteNode::heartbeat_check_done(HeartbeatCheck result) {
  if (!missing_ || !checking_) return;  // its heartbeat came back meanwhile, or it is lost already
  checking_ = false;
  switch (result) {
    case HeartbeatCheck::written_back: return heartbeat_.keep_waiting();  // for the heartbeat it restarts
    case HeartbeatCheck::abandoned: return;                               // the timer armed decides
    case HeartbeatCheck::not_the_cause: break;
  }
  missing_ = false;
  heartbeat_.declare_offline();
}

void RemoteNode::went_offline() {
  journal::log(journal::Event::device_lost, spdlog::level::warn, where_,
               fmt::format("{}: node {} lost: no heartbeat for {} ms", loop_.bus().uri(), node_id(),
                           heartbeat_timeout_.count()),
               {{journal::kHeartbeatTimeoutMs, std::to_string(heartbeat_timeout_.count())}});
  missing_ = false;
  checking_ = false;
  candidate_.reset();
  for (auto* d : drivers_) d->on_nmt_change(believed_, false);
  if (boot_up_pending_) booted(NmtState::boot_up);  // a boot-up and then silence: its heartbeat is off at power-on
  configured_ = false;
  emit(Event::lost);
}

// A device told to be operational that reports pre-operational or stopped (believed: on
// evidence) may have been reset without its boot-up reaching the master: its configuration may
// be gone. The state reported right after a command may predate it, so a difference counts once
// a heartbeat has confirmed the command, or once a whole heartbeat timeout has passed without.
void RemoteNode::check_commanded(NmtState state) {
  if (commanded_ == NmtState::unknown) return;
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
  ++stats_.emergencies_by_class[static_cast<std::size_t>(emcy_class(e->error_code))];
  errors_.apply(*e);
  if (emcy_log_.allow()) {
    journal::log(journal::Event::emcy, e->is_reset() ? spdlog::level::info : spdlog::level::warn, where_,
                 fmt::format("{}: node {} EMCY {:04X}h ({}), register {:02X}h{}", loop_.bus().uri(), node_id(),
                             e->error_code, emcy_family(e->error_code), e->error_register, held_back_note(emcy_log_)),
                 {{journal::kEmcyCode, fmt::format("{:04X}", e->error_code)},
                  {journal::kEmcyRegister, fmt::format("{:02X}", e->error_register)},
                  {journal::kEmcyManufacturer, fmt::format("{:02X}", fmt::join(e->manufacturer, ""))}});
  }
  for (auto* d : drivers_) d->on_emcy(*e);
}

}  // namespace lb::canopen
