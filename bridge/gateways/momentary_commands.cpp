#include "gateways/momentary_commands.hpp"

namespace lb::gateways {

MomentaryCommands::MomentaryCommands(canopen::BusLoop& loop, std::function<void(unsigned, bool)> set_bit,
                                     std::function<void()> changed, std::chrono::milliseconds hold)
    : loop_(loop), set_bit_(std::move(set_bit)), changed_(std::move(changed)), hold_(hold) {}

void MomentaryCommands::pulse(unsigned bit) {
  auto it = held_.find(bit);
  if (it == held_.end()) {
    // One timer per bit, created on first use (on the loop thread, as BusLoop allows).
    const auto timer = loop_.create_timer([this, bit] {
      held_.at(bit).active = false;
      set_bit_(bit, false);
      changed_();
    });
    it = held_.emplace(bit, Held{timer, false}).first;
  }
  it->second.active = true;
  set_bit_(bit, true);
  changed_();
  loop_.arm_timer(it->second.timer, hold_);
}

}  // namespace lb::gateways
