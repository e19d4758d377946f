#include "app/saw_text.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "app/word_text.hpp"

namespace lb::app {

namespace msg = linebridge_msgs::msg;

std::string to_text(msg::SawCountMode m) { return m == msg::CORRUGATED_PIPE ? "corrugated pipe" : "smooth pipe"; }

std::string to_text(const msg::SawStatus& s) {
  using Binding = linebridge_msgs::bindings::Saw;
  const auto& w = s.status_word();
  const auto& c = s.control_word();
  const std::string bits = status_word_text<Binding>(w);
  const std::string pressed = pressed_text<Binding>(c);
  const std::string toggles = toggles_text<Binding>(c);
  return fmt::format("{} {} | saw counter {:8.4f} m  speed {:7.3f} m/min  pulses {:>10} | status {:04X}h [{}] | "
                     "set: program {}, {}, wall-thickening {}, length {:.4f} m, sync {:.2f} %{}{}{}{}{}",
                     clock_text(s.stamp()), state_text(s.health()), s.actual_saw_counter_m(),
                     s.product_speed_m_per_min(), s.counter_value(), w.raw(), bits, c.saw_program_on() ? "on" : "off",
                     to_text(c.count_mode()), c.wall_thickening() ? "on" : "off", s.product_length_set_m(),
                     s.sync_speed_set_percent(), toggles.empty() ? "" : ", toggles [" + toggles + "]",
                     pressed.empty() ? "" : ", pressed [" + pressed + "]",
                     s.pdo_length_errors() ? fmt::format(" | {} short PDOs", s.pdo_length_errors()) : "",
                     errors_text(s.health()), other_values_text(s.other_values()));
}

std::string to_text(const msg::SawCut& c) {
  return fmt::format("{} CUT #{} at length {:.4f} m (saw counter before the cut {:.4f} m)", clock_text(c.stamp()),
                     c.cut_count(), c.length_in_force_m(), c.counter_before_cut_m());
}

}  // namespace lb::app
