#include "gateways/node/mandatory_devices.hpp"

#include <spdlog/spdlog.h>

namespace lb::gateways {

namespace {

void add_name(std::string& list, const std::string& name) { list += (list.empty() ? "" : ", ") + name; }

}  // namespace

MandatoryDevices::MandatoryDevices(canopen::BusLoop& loop, std::string bus, Policy policy, std::vector<Member> members)
    : loop_(loop), bus_(std::move(bus)), policy_(policy), members_(std::move(members)), status_(members_.size()) {
  for (std::size_t i = 0; i < members_.size(); ++i) {
    drivers_.push_back(std::make_unique<MemberDriver>(*this, i));
    members_[i].node->attach(*drivers_.back());
  }
}

bool MandatoryDevices::waits(std::size_t i) const {
  if (policy_ == Policy::report_only && passed_once_) return false;
  return !names_missing(i).empty();
}

std::string MandatoryDevices::names_missing(std::size_t except) const {
  std::string names;
  for (std::size_t j = 0; j < members_.size(); ++j) {
    if (j != except && members_[j].mandatory && status_[j].presence != Presence::passed)
      add_name(names, members_[j].name);
  }
  return names;
}

std::string MandatoryDevices::names_failed(std::size_t except) const {
  std::string names;
  for (std::size_t j = 0; j < members_.size(); ++j) {
    const auto p = status_[j].presence;
    if (j != except && members_[j].mandatory && (p == Presence::failed || p == Presence::lost))
      add_name(names, members_[j].name);
  }
  return names;
}

// The boot of member i passed every check and is about to send NMT start, unless the node is held.
void MandatoryDevices::starting(std::size_t i, const canopen::StartFacts& facts) {
  const auto& m = members_[i];
  auto& st = status_[i];
  auto& node = *m.node;
  if (m.mandatory) {
    st.presence = Presence::passed;
    st.why.clear();
    // After this boot's own NMT start (posted: it runs once the boot has sent it), so the
    // mandatory device is started first and the others follow.
    if (!gate_check_posted_) {
      gate_check_posted_ = true;
      loop_.post([this] {
        gate_check_posted_ = false;
        open_gate();
      });
    }
  }
  if (st.hold == Hold::stopped) return;                       // kept stopped until an operator starts it
  if (st.hold == Hold::none && node.operator_hold()) return;  // the operator's own stop or pre-operational
  const std::string failed = policy_ == Policy::stop_others ? names_failed(i) : std::string();
  if (!failed.empty() && (st.started || facts.found_operational)) {
    // It ran (or runs) while a mandatory device is gone: the line does not run without it.
    st.hold = Hold::stopped;
    st.hold_why = "mandatory device " + failed + " lost or failed its boot";
    st.kept_since_s = 0;
    node.hold(canopen::NmtCommand::stop);
    spdlog::warn(
        "{}: {} (node {}) is kept stopped: {} (when_mandatory_fails: stop_others); an operator's nmt start releases it",
        bus_, m.name, node.node_id(), st.hold_why);
    return;
  }
  if (waits(i)) {
    const auto missing = names_missing(i);
    if (facts.found_operational && failed.empty()) {
      // Only the bridge restarted, or a standby took the running line over: the mandatory devices
      // are most likely still being checked. A running line is not stopped for that; if one of
      // them fails, it is stopped then.
      if (st.hold == Hold::waiting) node.release_hold();
      st.hold = Hold::none;
      st.started = true;
      spdlog::info("{}: {} (node {}) {}: left running while mandatory device {} is checked", bus_, m.name,
                   node.node_id(), facts.adopted ? "adopted running at the takeover" : "found running", missing);
      return;
    }
    st.hold = Hold::waiting;
    st.hold_why = "waiting for mandatory device " + missing;
    node.hold(canopen::NmtCommand::enter_pre_operational);
    spdlog::info("{}: {} (node {}) configured, kept pre-operational: waiting for mandatory device {} (CiA 302-2: "
                 "no device is started before the mandatory ones passed their boot)",
                 bus_, m.name, node.node_id(), missing);
    return;
  }
  if (st.hold == Hold::waiting) node.release_hold();
  st.hold = Hold::none;
  st.started = true;
}

void MandatoryDevices::mastering() {
  if (!standing_by_) return;
  standing_by_ = false;
  spdlog::info("{}: mastered from now on: the mandatory devices' state is taken from the bus (adopted running: "
               "passed; any other: missing until its boot passes)",
               bus_);
}

void MandatoryDevices::event(std::size_t i, canopen::NodeEvent e) {
  if (standing_by_ || !members_[i].mandatory) return;
  switch (e) {
    case canopen::NodeEvent::lost: return gone(i, Presence::lost, "its heartbeat was lost");
    case canopen::NodeEvent::boot_up:
    case canopen::NodeEvent::unexpected_state:
      // Its configuration may be gone: it is booted again, and until that passes it is missing
      // (under stop_others a device that boots meanwhile waits for it). Not a failure yet.
      if (status_[i].presence == Presence::passed) status_[i].presence = Presence::booting;
      return;
    case canopen::NodeEvent::returned: return;  // its boot follows
  }
}

void MandatoryDevices::boot_finished(std::size_t i, const canopen::BootReport& report) {
  // Off the loop thread only while the bridge shuts down (its SDO client completes what is
  // pending, failing a boot under way): an exiting bridge must not stop the line.
  if (!loop_.on_loop_thread()) return;
  auto& st = status_[i];
  if (report.started) st.started = true;
  if (!members_[i].mandatory || report.started || report.held_by_operator) return;
  if (report.error) gone(i, Presence::failed, "its boot failed: " + report.error->message);
}

void MandatoryDevices::gone(std::size_t i, Presence presence, std::string why) {
  auto& st = status_[i];
  const bool was_gone = st.presence == Presence::failed || st.presence == Presence::lost;
  st.presence = presence;
  st.why = std::move(why);
  if (was_gone) return;  // one reaction per loss: an absent device fails its boot every retry
  if (policy_ == Policy::stop_others) return stop_others(i);
  spdlog::warn("{}: mandatory device {} (node {}): {}: the line runs on (when_mandatory_fails: report_only)", bus_,
               members_[i].name, members_[i].node->node_id(), st.why);
}

void MandatoryDevices::stop_others(std::size_t failed) {
  const auto& f = members_[failed];
  std::string stopped;
  for (std::size_t j = 0; j < members_.size(); ++j) {
    auto& st = status_[j];
    auto& node = *members_[j].node;
    // Never started (it waits), already held by the line, or stopped by an operator: nothing to do.
    if (j == failed || !st.started || st.hold != Hold::none || node.operator_hold()) continue;
    st.hold = Hold::stopped;
    st.hold_why = "mandatory device " + f.name + " " + status_[failed].why;
    st.kept_since_s = 0;
    node.hold(canopen::NmtCommand::stop);
    // A boot under way keeps asking it by SDO, which a stopped device does not answer: held only,
    // its boot ends by stopping it. One that is gone gets it at its next boot the same way.
    // (Configured: its last boot ended, whatever its heartbeat says yet.)
    const bool boot_under_way = !node.configured() && members_[j].booting && members_[j].booting();
    if (node.online() && !boot_under_way) {
      if (auto r = node.command(canopen::NmtCommand::stop); !r) {
        spdlog::warn("{}: {}: NMT stop could not be sent: {}", bus_, members_[j].name, r.error().message);
      }
    }
    add_name(stopped, members_[j].name);
  }
  if (stopped.empty()) {
    spdlog::warn("{}: mandatory device {} (node {}): {}: nothing the bridge started runs; the others wait for it", bus_,
                 f.name, f.node->node_id(), status_[failed].why);
    return;
  }
  spdlog::warn(
      "{}: mandatory device {} (node {}): {}: NMT stop to {} (when_mandatory_fails: stop_others); kept stopped "
      "until an operator starts them (nmt start), also when {} comes back",
      bus_, f.name, f.node->node_id(), status_[failed].why, stopped, f.name);
}

void MandatoryDevices::open_gate() {
  if (!names_missing(members_.size()).empty()) return;
  passed_once_ = true;
  std::string started, later;
  for (std::size_t j = 0; j < members_.size(); ++j) {
    auto& st = status_[j];
    if (st.hold != Hold::waiting) continue;
    auto& node = *members_[j].node;
    node.release_hold();
    st.hold = Hold::none;
    st.hold_why.clear();
    // Configured and kept pre-operational by its boot: started now, as an operator's nmt start
    // would. One whose boot has not ended (or that was lost meanwhile) is started by its boot.
    if (node.configured() && node.commanded_state() == canopen::NmtState::pre_operational) {
      if (auto r = node.command(canopen::NmtCommand::start); !r) {
        spdlog::warn("{}: {}: NMT start could not be sent: {}", bus_, members_[j].name, r.error().message);
        continue;
      }
      st.started = true;
      add_name(started, members_[j].name);
    } else {
      add_name(later, members_[j].name);
    }
  }
  if (!started.empty() || !later.empty()) {
    spdlog::info("{}: every mandatory device passed its boot: NMT start to {}{}", bus_,
                 started.empty() ? "none yet" : started,
                 later.empty() ? "" : "; started when their boot passes: " + later);
  }
}

void MandatoryDevices::kept_stop(std::size_t i, const KeptHold& hold) {
  auto& st = status_[i];
  st.hold = Hold::stopped;
  st.hold_why = hold.reason.empty() ? std::string("stopped by the line") : hold.reason;
  st.kept_since_s = hold.since_s;
  // HoldKeeper::restore put it on the node and logged it; held here too, whoever restored it.
  if (members_[i].node->operator_hold() != canopen::NmtCommand::stop) members_[i].node->hold(canopen::NmtCommand::stop);
}

HoldKeeper::LineHold MandatoryDevices::line_hold(std::size_t i) const {
  const auto& st = status_[i];
  switch (st.hold) {
    case Hold::none: return {};
    case Hold::waiting: return {HoldKeeper::LineHold::Kind::waiting, st.hold_why};
    case Hold::stopped: return {HoldKeeper::LineHold::Kind::stopped, st.hold_why};
  }
  return {};
}

void MandatoryDevices::operator_command(std::size_t i, canopen::NmtCommand command) {
  auto& st = status_[i];
  // The hold on the node is the operator's from now on (a stop, pre-operational), or released by
  // them (a start, a reset: its next boot decides anew).
  st.hold = Hold::none;
  st.hold_why.clear();
  st.kept_since_s = 0;
  if (command != canopen::NmtCommand::start) return;
  st.started = true;
  if (const auto missing = names_missing(i); !missing.empty()) {
    spdlog::warn("{}: {} started by an operator while mandatory device {} is missing", bus_, members_[i].name, missing);
  }
}

std::vector<std::string> MandatoryDevices::missing() const {
  std::vector<std::string> names;
  if (standing_by_) return names;  // nothing is booted by this bridge yet: the master of the moment knows
  for (std::size_t j = 0; j < members_.size(); ++j) {
    if (members_[j].mandatory && status_[j].presence != Presence::passed) names.push_back(members_[j].name);
  }
  return names;
}

std::string MandatoryDevices::state() const {
  if (standing_by_) return "standing by: the mandatory devices are judged from the takeover on, as the bus shows them";
  std::string held;
  for (std::size_t j = 0; j < members_.size(); ++j) {
    if (status_[j].hold == Hold::stopped)
      add_name(held, members_[j].name + (status_[j].kept_since_s != 0 ? " (since before the bridge restarted)" : ""));
  }
  const auto kept = held.empty() ? std::string() : "; kept stopped until an operator starts them: " + held;
  std::string failed;
  for (std::size_t j = 0; j < members_.size(); ++j) {
    const auto p = status_[j].presence;
    if (members_[j].mandatory && (p == Presence::failed || p == Presence::lost)) {
      failed += (failed.empty() ? "" : "; ") + members_[j].name + ": " + status_[j].why;
    }
  }
  if (!failed.empty()) {
    return "mandatory device missing (" + failed + ")" +
           (policy_ == Policy::stop_others ? " (when_mandatory_fails: stop_others)" + kept
                                           : std::string(": the line runs on (when_mandatory_fails: report_only)"));
  }
  if (const auto missing = names_missing(members_.size()); !missing.empty()) {
    if (policy_ == Policy::report_only && passed_once_) return "mandatory device " + missing + " is being booted again";
    return "waiting for mandatory device " + missing + ": no device of the bus is started before it passed its boot" +
           kept;
  }
  return held.empty() ? std::string() : "every mandatory device passed its boot" + kept;
}

std::string_view MandatoryDevices::held_as(std::size_t i) const {
  switch (status_[i].hold) {
    case Hold::none: return {};
    case Hold::waiting: return "waiting for a mandatory device";
    case Hold::stopped: return "stopped by the line";
  }
  return {};
}

std::string MandatoryDevices::hold_of(std::size_t i) const {
  const auto& st = status_[i];
  switch (st.hold) {
    case Hold::none: return {};
    case Hold::waiting: return st.hold_why + " (configured, kept pre-operational; started when it passes its boot)";
    case Hold::stopped:
      return "stopped: " + st.hold_why +
             (st.kept_since_s != 0
                  ? " (kept from before the bridge restarted; held since " + utc_text(st.kept_since_s) + ")"
                  : std::string()) +
             "; an operator's nmt start releases it";
  }
  return {};
}

}  // namespace lb::gateways
