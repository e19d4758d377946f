#include "app/feeder_text.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <vector>

#include "app/common_text.hpp"

namespace lb::app {

namespace msg = linebridge_msgs::msg;

namespace {

std::string function_text(const char* name, const msg::FeederFunction& f) {
  if (!f.valid()) return fmt::format("{} ?{:02b}b", name, f.raw());
  return fmt::format("{} {}", name, f.state());
}

std::string loom_text(const msg::LoomSide& l) {
  if (!l.seen()) return "loom: nothing seen yet";
  std::vector<std::string> picks;
  for (const auto& p : l.pick_insertion()) {
    picks.push_back(p.valid() ? fmt::format("{}({})", p.kind(), fmt::join(p.colours(), ","))
                              : fmt::format("invalid {:02X}h", p.raw()));
  }
  return fmt::format("loom: {}, max speed {} 1/min, width {:.2f} m, trigger {}, picks [{}]{}", to_text(l.loom_status()),
                     l.maximum_speed_per_min(), l.loom_width_m(), to_text(l.trigger_signal()), fmt::join(picks, " "),
                     l.digital_outputs().empty()
                         ? ""
                         : fmt::format(", outputs [{:02X}]", fmt::join(l.digital_outputs(), " ")));
}

}  // namespace

std::string to_text(const msg::FeederCode& c) {
  if (c.valid() && !c.name().empty()) return c.name();
  return fmt::format("undefined code {:02X}h", c.raw());
}

std::string to_text(const msg::FeederStatus& s) {
  std::string out = fmt::format("{} {} | {} feeder(s) | control box: {} | FF10h bitmap {:08X}h{}{}{}\n  {}\n",
                                clock_text(s.stamp()), state_text(s.health()),
                                s.feeder_count_read() ? std::to_string(s.feeder_count()) : "?",
                                s.control_box_error_read() ? to_text(s.control_box_error()) : "not read",
                                s.error_bitmap(),
                                s.pdo_length_errors() ? fmt::format(" | {} short PDOs", s.pdo_length_errors()) : "",
                                errors_text(s.health()), other_values_text(s.other_values()), loom_text(s.loom()));
  for (const auto& f : s.feeders()) {
    const auto& fn = f.functions();
    out += fmt::format("  feeder {:>3}: {}{} | condition {} | {}\n", f.number(),
                       f.status_read() ? to_text(f.status()) : "not read", f.in_error() ? " IN ERROR" : "",
                       f.error_condition_read() ? to_text(f.error_condition()) : "not read",
                       f.functions_read()
                           ? fmt::format("{}, {}, {}, {}, {}, {}, {}, {}", function_text("brush", fn.brush_release()),
                                         function_text("winding", fn.winding_direction()),
                                         function_text("angle-trigger", fn.angle_trigger_monitoring()),
                                         function_text("yarn-break", fn.yarn_break_sensor()),
                                         function_text("knot", fn.input_knot_detection_sensor()),
                                         function_text("yarn-quality", fn.yarn_quality_sensor()),
                                         function_text("rotation", fn.rotation_direction_sensor()),
                                         function_text("tks", fn.tks_sensor()))
                           : "functions not read");
  }
  return out;
}

std::string to_text(const msg::FeederUnwinding& u) {
  return fmt::format("{} UNWINDING feeder {} winding {} time {:.1f} ms{}", clock_text(u.stamp()), u.feeder_selected(),
                     u.winding_number(), u.coil_unwinding_time_ms(),
                     u.in_range() ? "" : " (outside the printed range)");
}

std::string to_text(const msg::FeederError& e) {
  return fmt::format("{} FEEDER {} {} (bitmap {:08X}h){}", clock_text(e.stamp()), e.feeder(),
                     e.in_error() ? "IN ERROR" : "error cleared", e.bitmap(),
                     e.detail_read() ? ": " + to_text(e.condition()) : (e.remark().empty() ? "" : ": " + e.remark()));
}

}  // namespace lb::app
