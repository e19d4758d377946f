#include "canopen/error_control.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>

namespace lb::canopen {

ErrorControl::ErrorControl(BusLoop& loop, RemoteNode& node, BootSequence& boot, Settings settings, Listener listener)
    : loop_(loop), node_(node), boot_(boot), settings_(settings), listener_(std::move(listener)) {
  timer_ = loop_.create_timer([this] {
    const std::string why = waiting_;
    waiting_.clear();
    boot_now(why);
  });
  node_.on_event([this](RemoteNode::Event e, NmtState s) { on_event(e, s); });
}

void ErrorControl::start() { boot_now("start-up"); }

std::string ErrorControl::state() const {
  if (!waiting_.empty()) return waiting_;
  return boot_.step();
}

void ErrorControl::on_event(RemoteNode::Event event, NmtState reported) {
  switch (event) {
    case RemoteNode::Event::boot_up:
      if (storm()) return;
      return boot_now("boot-up");
    case RemoteNode::Event::lost:
      if (boot_.report().started) ++counters_.state_unknown;
      // Nothing to configure while it is gone, but a device whose heartbeat producer was reset to
      // 0 only comes back if the master asks: probe it (the boot's first step) until it answers.
      if (!boot_.running() && waiting_.empty()) boot_now("heartbeat lost");
      return;
    case RemoteNode::Event::returned:
      if (boot_.running()) return boot_.heartbeat_back();  // a boot under way goes on
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
    if (auto r = node_.command(NmtCommand::reset_node); r) return;  // its boot-up starts the boot
  }
  boot_now(why);
}

void ErrorControl::boot_now(const std::string& why) {
  loop_.disarm_timer(timer_);
  waiting_.clear();
  ++counters_.boots;
  spdlog::info("{}: node {}: boot ({})", loop_.bus().uri(), node_.node_id(), why);
  boot_.run([this](const BootReport& r) { finished(r); });
}

void ErrorControl::boot_after(std::chrono::milliseconds delay, const std::string& why) {
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
  } else {
    ++counters_.boot_failures;
    boot_after(settings_.retry, boot_.step() + fmt::format("; next try in {} ms", settings_.retry.count()));
  }
  if (listener_) listener_(report);
}

}  // namespace lb::canopen
