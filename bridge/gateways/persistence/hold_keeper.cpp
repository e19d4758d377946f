#include "gateways/persistence/hold_keeper.hpp"

#include <spdlog/spdlog.h>

#include <chrono>

namespace lb::gateways {

namespace {

std::int64_t now_unix_s() {
  return std::chrono::duration_cast<std::chrono::seconds>(std::chrono::system_clock::now().time_since_epoch()).count();
}

}  // namespace

HoldKeeper::HoldKeeper(canopen::BusLoop& loop, canopen::RemoteNode& node, SetValueStore& store, KeptHold::Key key,
                       std::string device)
    : loop_(loop), node_(node), store_(store), key_(std::move(key)), device_(std::move(device)) {
  node_.attach(*this);
}

std::optional<KeptHold> HoldKeeper::restore() {
  const auto& held = store_.restored_holds();
  const auto it = held.find(key_);
  if (it == held.end()) return std::nullopt;
  kept_ = it->second;
  from_before_ = true;
  spdlog::warn("{} (node {}): {}, kept from before the bridge restarted: its boots put it back {} instead of starting "
               "it; an operator's nmt start releases it",
               device_, key_.node_id, describe(*kept_),
               kept_->command() == canopen::NmtCommand::stop ? "in stopped" : "in pre-operational");
  node_.hold(kept_->command());
  return kept_;
}

void HoldKeeper::operator_command(canopen::NmtCommand /*command*/) {
  by_operator_ = true;
  on_hold(node_.operator_hold());
}

void HoldKeeper::on_hold(const std::optional<canopen::NmtCommand>& /*hold*/) noexcept {
  // Settled once whatever changed the hold has been handled (see the header).
  if (settle_posted_) return;
  settle_posted_ = true;
  loop_.post([this] { settle(); });
}

std::optional<KeptHold> HoldKeeper::holder_now() const {
  const auto& hold = node_.operator_hold();
  if (!hold) return std::nullopt;
  const auto line = line_view_ ? line_view_() : LineHold{};
  KeptHold now;
  switch (line.kind) {
    case LineHold::Kind::waiting: return std::nullopt;  // decided anew at every start
    case LineHold::Kind::stopped:
      now.holder = KeptHold::Holder::line_stop;
      now.reason = line.reason;
      break;
    case LineHold::Kind::none:
      // A line's stop kept from before the restart on a bus that has no mandatory device any more:
      // nothing but an operator takes it over.
      if (!line_view_ && !by_operator_ && kept_ && kept_->holder == KeptHold::Holder::line_stop &&
          *hold == canopen::NmtCommand::stop) {
        return kept_;
      }
      now.holder = *hold == canopen::NmtCommand::stop ? KeptHold::Holder::operator_stop
                                                      : KeptHold::Holder::operator_pre_operational;
      break;
  }
  if (kept_ && kept_->holder == now.holder && kept_->reason == now.reason) return kept_;  // since when it was set
  now.since_s = now_unix_s();
  return now;
}

void HoldKeeper::settle() {
  settle_posted_ = false;
  auto now = holder_now();
  if (now == kept_) return;
  from_before_ = false;
  if (now) {
    spdlog::info("{} (node {}): {}: kept across restarts of the bridge", device_, key_.node_id, describe(*now));
  } else if (kept_) {
    spdlog::info("{} (node {}): no longer held ({})", device_, key_.node_id, describe(*kept_));
  }
  kept_ = now;
  store_.save_hold(key_, std::move(now));
}

std::string HoldKeeper::note() const {
  if (!kept_) return {};
  return describe(*kept_) + (from_before_ ? ", kept from before the bridge restarted" : "");
}

}  // namespace lb::gateways
