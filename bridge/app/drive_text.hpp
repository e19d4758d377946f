#pragma once
// A drive's status sample as one human-readable line, for linebridge-cli, the same for every drive
// type (its words by its binding's field names: word_text.hpp), so a drive type needs no rendering
// of its own.

#include <fmt/format.h>

#include <string>

#include "app/common_text.hpp"
#include "app/word_text.hpp"
#include "msgs/word_bindings.hpp"

namespace lb::app {

template <class Binding>
std::string drive_status_text(const typename Binding::Status& s) {
  const auto pressed = pressed_text<Binding>(s.control_word());
  const auto toggles = toggles_text<Binding>(s.control_word());
  return fmt::format(
      "{} {} | speed {:7.2f} % (echo {:7.2f} %) load {:6.2f} % product {:8.3f} m/min | status {:04X}h [{}] | "
      "set: extruder {}, speed {:.2f} %{}{}{}{}{}{}{}",
      clock_text(s.stamp()), state_text(s.health()), s.speed_actual_percent(), s.speed_set_echo_percent(),
      s.load_actual_percent(), s.product_speed_m_per_min(), s.status_word().raw(),
      status_word_text<Binding>(s.status_word()), s.control_word().extruder_running() ? "running" : "stopped",
      s.speed_set_percent(), toggles.empty() ? "" : ", toggles [" + toggles + "]",
      pressed.empty() ? "" : ", pressed [" + pressed + "]", s.set_echo_mismatch() ? " | SET ECHO MISMATCH" : "",
      s.manufacturer_status_word_present()
          ? fmt::format(" | manufacturer status word {:04X}h", s.manufacturer_status_word())
          : "",
      s.pdo_length_errors() ? fmt::format(" | {} short PDOs", s.pdo_length_errors()) : "", errors_text(s.health()),
      other_values_text(s.other_values()));
}

}  // namespace lb::app
