#include "canopen/node_state_machine.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <string_view>

namespace lb::canopen {

std::string_view to_string(NodeState state) {
  switch (state) {
    case NodeState::unknown: return "unknown";
    case NodeState::booting: return "booting";
    case NodeState::boot_failed: return "boot failed";
    case NodeState::running_unmanaged: return "running unmanaged";
    case NodeState::operational: return "operational";
    case NodeState::stopped_by_operator: return "stopped by operator";
    case NodeState::resetting: return "resetting";
    case NodeState::lost: return "lost";
  }
  return "?";
}

NodeStateMachine::NodeStateMachine(BusLoop& loop, RemoteNode& node, SdoClient& sdo, BootSequence::Settings boot,
                                   Settings settings)
    : loop_(loop), node_(node), boot_(loop, node, sdo, std::move(boot)), settings_(settings) {
  node_.attach(*this);
  node_.on_heartbeat_missing([this] { check_heartbeat_producer(); });
  timer_ = loop_.create_timer([this] {
    const std::string why = waiting_;
    waiting_.clear();
    boot_now(why);
  });
  reset_timer_ = loop_.create_timer([this] {
    if (boot_.running()) return;  // its boot-up came and started one
    boot_now(fmt::format("no boot-up within {} ms after an NMT reset (lost?): its state is unknown",
                         settings_.reset_bound.count()));
  });
}

void NodeStateMachine::enter(NodeState next, std::string_view why) {
  if (next == state_) return;
  spdlog::info("{}: node {}: {} -> {} ({})", loop_.bus().uri(), node_.node_id(), to_string(state_), to_string(next),
               why);
  state_ = next;
  ++counters_.transitions;
  node_.tell([next](NodeDriver& d) { d.on_state(next); });
}

NodeState NodeStateMachine::silent_state() const {
  return node_.last_heartbeat_ns() == 0 && state_ == NodeState::unknown ? NodeState::unknown : NodeState::lost;
}

// Still checking and configuring (not the reads for the record after the start): what comes back
// in between is its to handle. After the start, a loss or a return makes the state unknown again.
bool NodeStateMachine::boot_under_way() const {
  return boot_.running() && !boot_.report().started && !boot_.report().held_by_operator;
}

void NodeStateMachine::start() {
  started_ = true;
  boot_now("start-up");
}

void NodeStateMachine::take_over(std::optional<NmtCommand> last_command) {
  started_ = true;
  const auto reported = node_.state();
  std::optional<NmtState> held_in;
  if (last_command == NmtCommand::stop) held_in = NmtState::stopped;
  if (last_command == NmtCommand::enter_pre_operational) held_in = NmtState::pre_operational;
  const bool held = held_in && reported == *held_in;
  const bool runs = reported == NmtState::operational && (!last_command || *last_command == NmtCommand::start);
  if (!node_.online() || node_.boot_up_pending() || !(runs || held)) {
    return boot_now(fmt::format("taking the bus over: it is not heard operational ({}{})", to_string(reported),
                                node_.online() ? "" : ", not heard"));
  }
  if (auto r = node_.use_pdos(boot_.line_pdos()); !r) {
    return boot_now("taking the bus over: its PDOs as the line configures them were refused: " + r.error().message);
  }
  ++counters_.adopted;
  if (held) node_.hold(*last_command);
  node_.adopt(reported);  // before its drivers start: what they send at once may go out
  node_.starting({true, false, {}, true});
  spdlog::info("{}: node {}: adopted {}{} (no NMT, no SDO download; its identity is read after the first SYNC)",
               loop_.bus().uri(), node_.node_id(), to_string(reported),
               held ? " as the master before held it" : ", as it runs");
  adoption_ = Adoption::awaiting_sync;
  adoption_detail_ = "adopted at a takeover (no NMT, no SDO download): its identity is read after the first SYNC";
  enter(held ? NodeState::stopped_by_operator : NodeState::operational,
        held ? "adopted at a takeover, held as the master before left it" : "adopted as it ran at a takeover");
}

// Posted from the first SYNC's cycle: every frame of that cycle (the SYNC that ends the takeover's
// gap, every node's RPDOs) is out before the first request of the reading.
void NodeStateMachine::on_sync() noexcept {
  if (adoption_ != Adoption::awaiting_sync) return;
  adoption_ = Adoption::reading;
  loop_.post([this, gen = adoption_generation_] {
    if (gen == adoption_generation_ && adoption_ == Adoption::reading) read_adopted();
  });
}

void NodeStateMachine::read_adopted() {
  ++adoption_generation_;
  if (node_.state() == NmtState::stopped) {
    adoption_ = Adoption::awaiting_state;
    adoption_detail_ =
        "adopted at a takeover (no NMT, no SDO download), stopped: its identity is read once it is heard in another "
        "state (a stopped device answers no SDO, CiA 301)";
    return;
  }
  adoption_ = Adoption::reading;
  adoption_detail_ = "adopted at a takeover (no NMT, no SDO download): reading its identity (SDO uploads only)";
  boot_.identity_reader().read_all([this, gen = adoption_generation_] { return gen != adoption_generation_; },
                                   [this](IdentityReader::Reading r) { adopted_read(std::move(r)); });
}

// What an adopted device said about itself reaches the drivers as a boot's report would (info,
// error history, 6010h follow in DeviceServices), with `adopted` set and nothing in `error`: no
// boot ran, and none failed.
void NodeStateMachine::adopted_read(IdentityReader::Reading reading) {
  // Completed by a client that is being destroyed (the bridge stops): nothing to report.
  if (!loop_.on_loop_thread()) return;
  auto& check = reading.check;
  if (!check.answered && node_.state() == NmtState::stopped) {
    // Stopped meanwhile (an operator's stop): asked again once it answers SDO.
    read_adopted();
    return;
  }
  adoption_ = Adoption::read;
  const auto& uri = loop_.bus().uri();
  const auto id = node_.node_id();
  BootReport report;
  report.adopted = true;
  report.held_by_operator = node_.operator_hold().has_value();
  report.started = !report.held_by_operator;
  report.was_operational = node_.state() == NmtState::operational;
  report.pdos = boot_.line_pdos();
  report.heartbeat_producer_ms = reading.heartbeat_producer_ms;
  // The period a new state must be reported over to be believed (RemoteNode), as a boot sets it.
  if (const auto producer = reading.heartbeat_producer_ms)
    node_.set_heartbeat_producer(std::chrono::milliseconds(*producer));
  std::string found;
  if (check.error && check.answered) {
    ++counters_.adopted_identity_mismatches;
    found = fmt::format(
        "ITS IDENTITY IS NOT THE LINE'S: {} (a boot would fail with CiA 302-2 error {}); adopted at the takeover all "
        "the same, it runs on as the master before left it (a boot-up, a heartbeat loss or an operator's reset "
        "boots it)",
        check.error->message, check.error->code);
    report.warnings.push_back(found);
    spdlog::warn("{}: node {}: {}", uri, id, found);
  } else if (check.error) {
    found = "its identity could not be read: " + check.error->message;
    report.warnings.push_back(found);
    spdlog::warn("{}: node {}: adopted at the takeover, but {}", uri, id, found);
  } else {
    found = "its identity read (SDO uploads only) is what the line expects";
    spdlog::info("{}: node {}: adopted at the takeover: {}", uri, id, found);
  }
  for (auto& w : boot_.heartbeat_warnings(reading.heartbeat_producer_ms)) {
    spdlog::warn("{}: node {}: {}", uri, id, w);
    report.warnings.push_back(std::move(w));
  }
  report.identity = std::move(check.identity);
  adoption_detail_ = "adopted at a takeover (no NMT, no SDO download); " + found;
  node_.tell([&report](NodeDriver& d) { d.on_boot(report); });
}

void NodeStateMachine::abandon_adoption() {
  if (adoption_ == Adoption::none) return;
  ++adoption_generation_;
  adoption_ = Adoption::none;
  adoption_detail_.clear();
}

Result<void> NodeStateMachine::operator_command(NmtCommand command) {
  // A device whose boot did not pass (or whose state became unknown since) may have lost its
  // configuration: starting it would hand it RPDOs it may misread. Its boot starts it.
  if (command == NmtCommand::start && !node_.configured()) {
    const auto text = [](const BootError& e) {
      return e.code != 0 ? fmt::format("CiA 302-2 error {}: {}", e.code, e.message) : e.message;
    };
    const auto& e = boot_.report().error;
    std::string why = e ? text(*e) : detail();
    if (!e && last_failure_) why += "; its last boot failed: " + text(*last_failure_);
    return make_error(
        fmt::format("{}: has not passed its boot ({}): NMT start refused; the bridge starts it when its boot "
                    "passes (reset-node boots it again)",
                    to_string(state_), why));
  }
  // Kept before it is sent, so that the command is seen as held (on_command); put back as it was
  // when it cannot be sent.
  const auto before = node_.operator_hold();
  if (command == NmtCommand::stop || command == NmtCommand::enter_pre_operational)
    node_.hold(command);
  else
    node_.release_hold();  // a start (operational once its heartbeat says so), a reset (a boot follows)
  if (auto r = node_.command(command); !r) {
    if (before)
      node_.hold(*before);
    else
      node_.release_hold();
    return r;
  }
  if (command == NmtCommand::reset_node || command == NmtCommand::reset_communication) reset_sent(true);
  return {};
}

// A reset always leads to a boot: its boot-up starts one, and if none is believed within
// reset_bound (a lost boot-up), a boot begins anyway; the device is never taken for started
// meanwhile.
void NodeStateMachine::reset_sent(bool by_operator) {
  abandon_heartbeat_check();
  abandon_adoption();
  boot_.cancel();
  reset_unconfirmed_ = true;
  loop_.disarm_timer(timer_);
  if (by_operator) {
    recent_.clear();
    backoff_ = std::chrono::milliseconds(0);
  }
  waiting_ = "reset: waiting for its boot-up";
  loop_.arm_timer(reset_timer_, settings_.reset_bound);
  enter(NodeState::resetting, by_operator ? "an operator's NMT reset" : "NMT reset node sent to recover it");
}

std::string NodeStateMachine::detail() const {
  if (!waiting_.empty()) return waiting_;
  if (checking_heartbeat_producer_) {
    return "no heartbeat within its timeout, but heard by other frames of its own: checking its heartbeat producer "
           "time 1017h";
  }
  if (node_.heartbeat_missing()) return "its heartbeat producer time 1017h was written back: waiting for its heartbeat";
  // The boot's last step ("started") is history once an operator's stop or pre-operational took
  // the node out of operational: what holds it now is said instead.
  if (const auto& hold = node_.operator_hold(); hold && state_ == NodeState::stopped_by_operator) {
    return fmt::format("configured; kept {} by the operator (nmt start releases it){}",
                       *hold == NmtCommand::stop ? "stopped" : "pre-operational",
                       adoption_ == Adoption::none ? "" : "; " + adoption_detail_);
  }
  // Adopted at a takeover: no boot ran, whose step would say nothing.
  if (adoption_ != Adoption::none) return adoption_detail_;
  return boot_.step();
}

void NodeStateMachine::on_heartbeat(NmtState state) noexcept {
  // After a boot-up not judged yet the device may have just lost what a boot under way wrote: that
  // boot must not take this heartbeat for the one that follows its configuration and start it
  // (the boot-up, once believed, boots it again).
  if (!node_.boot_up_pending()) boot_.heard(state);
  // Adopted held stopped, now in a state that answers SDO (an operator's start, or pre-operational).
  if (adoption_ == Adoption::awaiting_state && state != NmtState::stopped && !node_.boot_up_pending()) read_adopted();
  // Started (or released by an operator) and now heard operational: the condition for RPDOs.
  if ((state_ == NodeState::booting || state_ == NodeState::stopped_by_operator) && node_.ready_for_pdos()) {
    enter(NodeState::operational, "started, heard operational");
  }
}

// Whoever sends it (an operator here, the line's reaction to a lost mandatory device through the
// node): a kept stop or pre-operational takes a configured node out of operational. One sent by a
// boot comes before the boot ends (not configured yet): its end decides (finished()).
void NodeStateMachine::on_command(NmtCommand command) noexcept {
  const auto& hold = node_.operator_hold();
  if (hold && *hold == command && node_.configured())
    enter(NodeState::stopped_by_operator, "a kept NMT stop or pre-operational");
}

void NodeStateMachine::on_event(NodeEvent event) noexcept {
  // Heard before the start-up boot began (the loop runs before start() is posted): that boot
  // checks it; acting on the event too would boot it twice (the second cancelling the first).
  if (!started_) return;
  switch (event) {
    case NodeEvent::boot_up:
      loop_.disarm_timer(reset_timer_);
      if (storm()) return;
      return boot_now("boot-up");
    case NodeEvent::lost:
      if (boot_.report().started) ++counters_.state_unknown;
      // After a reset a silence is expected: the bound on the wait for the boot-up decides.
      if (state_ == NodeState::resetting) return;
      if (state_ == NodeState::running_unmanaged) waiting_.clear();  // no retry timer stands behind that wait
      enter(NodeState::lost, "no heartbeat within its timeout");
      // Nothing to configure while it is gone, but a device whose heartbeat producer was reset to
      // 0 only comes back if the master asks: probe it (the boot's first step) until it answers.
      if (!boot_under_way() && waiting_.empty()) boot_now("heartbeat lost");
      return;
    case NodeEvent::returned:
      // Back after the silence of a reset: its boot-up (believed on evidence) or the bound on
      // waiting for it boots it.
      if (state_ == NodeState::resetting) return;
      if (boot_under_way()) {  // a boot under way goes on (it hears the heartbeat itself)
        enter(NodeState::booting, "heard while its boot probes it");
        return;
      }
      if (node_.configured()) return;
      if (storm()) return;
      return recover("its heartbeat came (back) while the bridge did not know its state");
    case NodeEvent::unexpected_state:
      ++counters_.state_unknown;
      if (storm()) return;
      return recover(node_.state() == NmtState::stopped ? "it reports stopped unasked"
                                                        : "it reports pre-operational unasked");
  }
}

void NodeStateMachine::recover(const char* why) {
  if (settings_.on_state_unknown == RecoveryAction::reset_node && reset_unconfirmed_) {
    // One reset per incident: a device whose reset outlasts its heartbeat timeout comes back
    // unknown once more, and resetting it again would loop.
    ++counters_.resets_spared;
    spdlog::warn("{}: node {}: {}: an NMT reset was sent and no boot has passed since: booted, not reset again",
                 loop_.bus().uri(), node_.node_id(), why);
  } else if (settings_.on_state_unknown == RecoveryAction::reset_node) {
    spdlog::warn("{}: node {}: {}: its configuration may be gone, NMT reset node", loop_.bus().uri(), node_.node_id(),
                 why);
    boot_.cancel();
    if (auto r = node_.command(NmtCommand::reset_node); r) return reset_sent(false);  // its boot-up starts the boot
  }
  boot_now(why);
}

void NodeStateMachine::boot_now(const std::string& why) {
  abandon_heartbeat_check();
  abandon_adoption();
  loop_.disarm_timer(timer_);
  loop_.disarm_timer(reset_timer_);
  waiting_.clear();
  ++counters_.boots;
  if (boot_log_.allow(why))
    spdlog::info("{}: node {}: boot ({}){}", loop_.bus().uri(), node_.node_id(), why, boot_log_.note());
  // A node not heard now is probed (the boot's first step): it stays unknown or lost until it answers.
  enter(node_.online() ? NodeState::booting : silent_state(), why);
  boot_.run([this](const BootReport& r) { finished(r); });
}

void NodeStateMachine::boot_after(std::chrono::milliseconds delay, const std::string& why) {
  abandon_heartbeat_check();
  abandon_adoption();
  boot_.cancel();
  waiting_ = why;
  loop_.arm_timer(timer_, delay);
  enter(node_.online() ? NodeState::boot_failed : silent_state(), why);
}

bool NodeStateMachine::storm() {
  const auto now = std::chrono::steady_clock::now();
  recent_.push_back(now);
  while (!recent_.empty() && now - recent_.front() > settings_.storm_window) recent_.pop_front();
  if (recent_.size() < settings_.storm_count) {
    backoff_ = std::chrono::milliseconds(0);
    return false;
  }
  if (backoff_.count() == 0) ++counters_.storms;
  backoff_ = std::min<std::chrono::milliseconds>(backoff_.count() == 0 ? settings_.retry : backoff_ * 2,
                                                 settings_.max_backoff);
  const auto why = fmt::format("boot-up storm: {} boot-ups or lost states within {} ms; next boot in {} ms",
                               recent_.size(), settings_.storm_window.count(), backoff_.count());
  spdlog::warn("{}: node {}: {}", loop_.bus().uri(), node_.node_id(), why);
  boot_after(backoff_, why);
  return true;
}

void NodeStateMachine::count_failure(const BootReport& report) {
  ++counters_.boot_failures;
  if (!report.error) return;
  const auto letter = static_cast<std::size_t>(report.error->code - 'A');
  if (report.error->code >= 'A' && letter < counters_.boot_failures_by_letter.size())
    ++counters_.boot_failures_by_letter[letter];
}

void NodeStateMachine::finished(const BootReport& report) {
  if (report.error) {
    last_failure_ = report.error;
  } else if (report.started || report.held_by_operator) {
    last_failure_.reset();
    reset_unconfirmed_ = false;  // the incident is over: the next one may reset it again
  }
  if (report.error) keep_hold();
  if (report.started) {
    ++counters_.boots_started;  // operational once heard so (on_heartbeat), which may be before this
  } else if (report.held_by_operator) {
    enter(NodeState::stopped_by_operator, "configured and kept as an operator left it");
  } else if (const auto& e = report.error; e && std::string_view("CDMNOJ").find(e->code) != std::string_view::npos &&
                                           node_.online() && node_.state() == NmtState::operational) {
    // It runs, and what failed does not change by asking again (its identity, a configuration it
    // refuses): kept running as it is and reported, not booted every retry interval for ever.
    // A boot-up, a heartbeat loss or an operator's reset boots it again.
    count_failure(report);
    waiting_ = boot_.step() + "; it runs on unmanaged (not started by this bridge); a boot-up, a heartbeat loss or an "
                              "operator's reset boots it again";
    spdlog::warn(
        "{}: node {}: boot failed while it runs: left running, not retried until it boots, is lost or is reset",
        loop_.bus().uri(), node_.node_id());
    enter(NodeState::running_unmanaged, fmt::format("boot error {} while it runs", e->code));
  } else {
    count_failure(report);
    boot_after(settings_.retry, boot_.step() + fmt::format("; next try in {} ms", settings_.retry.count()));
  }
  node_.tell([&report](NodeDriver& d) { d.on_boot(report); });
}

// A device an operator (or the line) holds stopped or pre-operational stays so when its boot fails:
// the boot would have put it back in that state, and a failed boot (its identity, a configuration
// it refuses, pdo_change_when_running: keep_running) must not leave it running. The hold's command
// is a stop: it goes out whenever the device is heard.
void NodeStateMachine::keep_hold() {
  const auto& hold = node_.operator_hold();
  if (!hold || !node_.heard()) return;
  const auto held_in = *hold == NmtCommand::stop ? NmtState::stopped : NmtState::pre_operational;
  if (node_.state() == held_in) return;
  if (auto r = node_.command(*hold); !r) {
    spdlog::warn("{}: node {}: held {} but its boot failed, and the command could not be sent: {}", loop_.bus().uri(),
                 node_.node_id(), to_string(held_in), r.error().message);
    return;
  }
  spdlog::warn("{}: node {}: held {} (an operator's or the line's hold) and its boot failed: NMT {} sent all the same",
               loop_.bus().uri(), node_.node_id(), to_string(held_in),
               *hold == NmtCommand::stop ? "stop" : "enter pre-operational");
}

// Its heartbeat stopped while it is heard: only a configured device whose boot is not under way
// is checked (a boot reads and writes 1017h itself).
void NodeStateMachine::check_heartbeat_producer() {
  using Check = RemoteNode::HeartbeatCheck;
  // A standby (not started) sends nothing a device acts on: its master checks.
  if (!started_ || boot_.running() || state_ == NodeState::resetting)
    return node_.heartbeat_check_done(Check::not_the_cause);
  checking_heartbeat_producer_ = true;
  boot_.check_heartbeat_producer([this](const BootSequence::ProducerCheck& c) {
    checking_heartbeat_producer_ = false;
    if (c.written_back) ++counters_.heartbeat_producer_rewrites;
    node_.heartbeat_check_done(c.written_back ? Check::written_back : Check::not_the_cause);
  });
}

void NodeStateMachine::abandon_heartbeat_check() {
  if (!checking_heartbeat_producer_) return;
  checking_heartbeat_producer_ = false;
  node_.heartbeat_check_done(RemoteNode::HeartbeatCheck::abandoned);
}

}  // namespace lb::canopen
