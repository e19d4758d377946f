#include "app/saw_text.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

namespace lb::app {

namespace msg = linebridge_msgs::msg;

std::string to_text(msg::SawCountMode m) { return m == msg::CORRUGATED_PIPE ? "corrugated pipe" : "smooth pipe"; }

std::string to_text(const msg::SawStatus& s) {
  const auto& w = s.status_word();
  const std::string bits = flags_text({{w.saw_ready(), "ready"},
                                       {w.saw_cutting(), "CUTTING"},
                                       {w.sample_request(), "sample-request"},
                                       {w.manual_cut_by_saw(), "manual-cut"},
                                       {w.fault(), "FAULT"},
                                       {w.alarm(), "ALARM"},
                                       {w.f1_running(), "f1-running"},
                                       {w.f2_running(), "f2-running"},
                                       {w.f3_running(), "f3-running"},
                                       {w.saw_program_enabled(), "program-enabled"},
                                       {w.cut_from_limit_switch(), "limit-switch"},
                                       {w.start_saw_program_requested(), "start-requested"}});
  const auto& c = s.control_word();
  const std::string pressed = flags_text({{c.manual_cut(), "manual_cut"},
                                          {c.tip_pulse(), "tip_pulse"},
                                          {c.stop_immediately(), "stop_immediately"},
                                          {c.f1_stop(), "f1_stop"},
                                          {c.f1_start(), "f1_start"},
                                          {c.f2_stop(), "f2_stop"},
                                          {c.f2_start(), "f2_start"},
                                          {c.f3_stop(), "f3_stop"},
                                          {c.f3_start(), "f3_start"}});
  return fmt::format("{} {} | saw counter {:8.4f} m  speed {:7.3f} m/min  pulses {:>10} | status {:04X}h [{}] | "
                     "set: program {}, {}, wall-thickening {}, length {:.4f} m, sync {:.2f} %{}{}{}{}",
                     clock_text(s.stamp()), state_text(s.health()), s.actual_saw_counter_m(),
                     s.product_speed_m_per_min(), s.counter_value(), w.raw(), bits, c.saw_program_on() ? "on" : "off",
                     to_text(c.count_mode()), c.wall_thickening() ? "on" : "off", s.product_length_set_m(),
                     s.sync_speed_set_percent(), pressed.empty() ? "" : ", pressed [" + pressed + "]",
                     s.pdo_length_errors() ? fmt::format(" | {} short PDOs", s.pdo_length_errors()) : "",
                     errors_text(s.health()), other_values_text(s.other_values()));
}

std::string to_text(const msg::SawCut& c) {
  return fmt::format("{} CUT #{} at length {:.4f} m (saw counter before the cut {:.4f} m)", clock_text(c.stamp()),
                     c.cut_count(), c.length_in_force_m(), c.counter_before_cut_m());
}

}  // namespace lb::app
