#include "canopen/error_control.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <string_view>

namespace lb::canopen {

ErrorControl::ErrorControl(BusLoop& loop, RemoteNode& node, BootSequence& boot, Settings settings, Listener listener)
    : loop_(loop), node_(node), boot_(boot), settings_(settings), listener_(std::move(listener)) {
  timer_ = loop_.create_timer([this] {
    const std::string why = waiting_;
    waiting_.clear();
    boot_now(why);
  });
  reset_timer_ = loop_.create_timer([this] {
    if (boot_.running()) return;  // its boot-up came and started one
    boot_now(fmt::format("no boot-up within {} ms after an NMT reset (lost?): its state is unknown", settings_.reset_bound.count()));
  });
  node_.on_event([this](RemoteNode::Event e, NmtState s) { on_event(e, s); });
}

// Still checking and configuring (not the reads for the record after the start): what comes back
// in between is its to handle. After the start, a loss or a return makes the state unknown again.
bool ErrorControl::boot_under_way() const {
  return boot_.running() && !boot_.report().started && !boot_.report().held_by_operator;
}

void ErrorControl::reset_sent(bool by_operator) {
  unmanaged_ = false;
  boot_.cancel();
  loop_.disarm_timer(timer_);
  if (by_operator) {
    recent_.clear();
    backoff_ = std::chrono::milliseconds(0);
  }
  waiting_ = "reset: waiting for its boot-up";
  resetting_ = true;
  loop_.arm_timer(reset_timer_, settings_.reset_bound);
}

void ErrorControl::start() { boot_now("start-up"); }

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

NodeState ErrorControl::node_state() const {
  if (resetting_) return NodeState::resetting;
  if (!node_.online()) return node_.last_heartbeat_ns() == 0 ? NodeState::unknown : NodeState::lost;
  if (unmanaged_) return NodeState::running_unmanaged;
  if (boot_under_way()) return NodeState::booting;
  if (node_.operator_hold() && node_.configured()) return NodeState::stopped_by_operator;
  if (node_.ready_for_pdos()) return NodeState::operational;
  if (boot_.report().error) return NodeState::boot_failed;
  return NodeState::booting;
}

std::string ErrorControl::state() const {
  if (!waiting_.empty()) return waiting_;
  return boot_.step();
}

void ErrorControl::on_event(RemoteNode::Event event, NmtState reported) {
  switch (event) {
    case RemoteNode::Event::boot_up:
      loop_.disarm_timer(reset_timer_);
      resetting_ = false;
      if (storm()) return;
      return boot_now("boot-up");
    case RemoteNode::Event::lost:
      if (boot_.report().started) ++counters_.state_unknown;
      if (unmanaged_) {  // no retry timer stands behind this wait: probe it like any lost device
        unmanaged_ = false;
        waiting_.clear();
      }
      // Nothing to configure while it is gone, but a device whose heartbeat producer was reset to
      // 0 only comes back if the master asks: probe it (the boot's first step) until it answers.
      if (!boot_under_way() && waiting_.empty()) boot_now("heartbeat lost");
      return;
    case RemoteNode::Event::returned:
      if (boot_under_way()) return;  // a boot under way goes on (it hears the heartbeat itself)
      if (node_.configured()) return;
      if (storm()) return;
      return recover("its heartbeat came (back) while the bridge did not know its state");
    case RemoteNode::Event::unexpected_state:
      ++counters_.state_unknown;
      if (storm()) return;
      return recover(reported == NmtState::stopped ? "it reports stopped unasked" : "it reports pre-operational unasked");
  }
}

void ErrorControl::recover(const char* why) {
  if (settings_.on_state_unknown == RecoveryAction::reset_node) {
    spdlog::warn("{}: node {}: {}: its configuration may be gone, NMT reset node", loop_.bus().uri(), node_.node_id(), why);
    boot_.cancel();
    if (auto r = node_.command(NmtCommand::reset_node); r) return reset_sent(false);  // its boot-up starts the boot
  }
  boot_now(why);
}

void ErrorControl::boot_now(const std::string& why) {
  unmanaged_ = false;
  resetting_ = false;
  loop_.disarm_timer(timer_);
  loop_.disarm_timer(reset_timer_);
  waiting_.clear();
  ++counters_.boots;
  if (boot_log_.allow(why)) spdlog::info("{}: node {}: boot ({}){}", loop_.bus().uri(), node_.node_id(), why, boot_log_.note());
  boot_.run([this](const BootReport& r) { finished(r); });
}

void ErrorControl::boot_after(std::chrono::milliseconds delay, const std::string& why) {
  unmanaged_ = false;
  boot_.cancel();
  waiting_ = why;
  loop_.arm_timer(timer_, delay);
}

bool ErrorControl::storm() {
  const auto now = std::chrono::steady_clock::now();
  recent_.push_back(now);
  while (!recent_.empty() && now - recent_.front() > settings_.storm_window) recent_.pop_front();
  if (recent_.size() < settings_.storm_count) {
    backoff_ = std::chrono::milliseconds(0);
    return false;
  }
  if (backoff_.count() == 0) ++counters_.storms;
  backoff_ = std::min<std::chrono::milliseconds>(backoff_.count() == 0 ? settings_.retry : backoff_ * 2, settings_.max_backoff);
  const auto why = fmt::format("boot-up storm: {} boot-ups or lost states within {} s; next boot in {} ms", recent_.size(),
                               settings_.storm_window.count(), backoff_.count());
  spdlog::warn("{}: node {}: {}", loop_.bus().uri(), node_.node_id(), why);
  boot_after(backoff_, why);
  return true;
}

void ErrorControl::finished(const BootReport& report) {
  if (report.started) {
    ++counters_.boots_started;
  } else if (report.held_by_operator) {
    // Configured and kept as the operator left it: nothing to retry.
  } else if (const auto& e = report.error;
             e && std::string_view("CDMNOJ").find(e->code) != std::string_view::npos && node_.online() &&
             node_.state() == NmtState::operational) {
    // It runs, and what failed does not change by asking again (its identity, a configuration it
    // refuses): kept running as it is and reported, not booted every retry interval for ever.
    // A boot-up, a heartbeat loss or an operator's reset boots it again.
    ++counters_.boot_failures;
    unmanaged_ = true;
    waiting_ = boot_.step() + "; it runs on unmanaged (not started by this bridge); a boot-up, a heartbeat loss or an "
                              "operator's reset boots it again";
    spdlog::warn("{}: node {}: boot failed while it runs: left running, not retried until it boots, is lost or is reset",
                 loop_.bus().uri(), node_.node_id());
  } else {
    ++counters_.boot_failures;
    boot_after(settings_.retry, boot_.step() + fmt::format("; next try in {} ms", settings_.retry.count()));
  }
  if (listener_) listener_(report);
}

}  // namespace lb::canopen
