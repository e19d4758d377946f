#pragma once
// Which generated word bindings (msgs/word_bindings.hpp) have a drive's shape, and the lookup of a
// drive type's binding by the IDL its registry entry names (profiles/device_types.hpp).

#include <string_view>
#include <utility>

#include "msgs/word_bindings.hpp"

namespace lb::gateways {

// A binding whose types have the drive's shape (the generated bindings include the saw's too).
template <class Binding>
concept DriveShaped = requires(typename Binding::Status s, const typename Binding::Setpoint sp) {
  s.speed_actual_percent(0.0);
  s.speed_set_echo_percent(0.0);
  s.control_word().extruder_running(true);
  sp.speed_set_percent();
};

// Calls f.template operator()<Binding>() for the drive-shaped binding of `idl`; false when there is
// none.
template <class F>
bool visit_drive(std::string_view idl, F&& f) {
  bool found = false;
  linebridge_msgs::bindings::visit(idl, [&]<class Binding>() {
    if constexpr (DriveShaped<Binding>) {
      found = true;
      f.template operator()<Binding>();
    }
  });
  return found;
}

}  // namespace lb::gateways
