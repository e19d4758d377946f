#include "app/saw_text.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <ctime>

namespace lb::app {

namespace msg = linebridge_msgs::msg;

std::string to_text(msg::NmtState s) {
  switch (s) {
    case msg::NMT_BOOT_UP: return "boot-up";
    case msg::NMT_STOPPED: return "stopped";
    case msg::NMT_OPERATIONAL: return "operational";
    case msg::NMT_PRE_OPERATIONAL: return "pre-operational";
    case msg::NMT_UNKNOWN: break;
  }
  return "unknown";
}

std::string clock_text(const msg::Time& t) {
  const std::time_t secs = t.sec();
  std::tm tm{};
  localtime_r(&secs, &tm);
  return fmt::format("{:02}:{:02}:{:02}.{:03}", tm.tm_hour, tm.tm_min, tm.tm_sec, t.nanosec() / 1'000'000);
}

std::string to_text(const msg::SawStatus& s) {
  const auto& w = s.status_word();
  std::string bits;
  const auto add = [&bits](bool on, const char* name) {
    if (on) bits += bits.empty() ? name : std::string(" ") + name;
  };
  add(w.saw_ready(), "ready");
  add(w.saw_cutting(), "CUTTING");
  add(w.sample_request(), "sample-request");
  add(w.manual_cut_by_saw(), "manual-cut");
  add(w.fault(), "FAULT");
  add(w.alarm(), "ALARM");
  add(w.f1_running(), "f1-running");
  add(w.f2_running(), "f2-running");
  add(w.f3_running(), "f3-running");
  add(w.saw_program_enabled(), "program-enabled");
  add(w.cut_from_limit_switch(), "limit-switch");
  add(w.start_saw_program_requested(), "start-requested");
  const auto& c = s.control_word();
  return fmt::format(
      "{} {:<15} {:<7} | saw counter {:8.4f} m  speed {:7.3f} m/min  pulses {:>10} | status {:04X}h [{}] | "
      "set: program {}, {} pipe, length {:.4f} m, sync {:.2f} %{}{}",
      clock_text(s.stamp()), to_text(s.health().nmt_state()), s.health().online() ? "online" : "OFFLINE", s.actual_saw_counter_m(),
      s.product_speed_m_per_min(), s.counter_value(), w.raw(), bits, c.saw_program_on() ? "on" : "off",
      c.count_mode() == msg::CORRUGATED_PIPE ? "corrugated" : "smooth", s.product_length_set_m(),
      s.sync_speed_set_percent(), s.pdo_length_errors() ? fmt::format(" | {} short PDOs", s.pdo_length_errors()) : "",
      s.health().active_errors().empty() ? "" : fmt::format(" | EMCY active: {:04X}", fmt::join(s.health().active_errors(), " ")));
}

std::string to_text(const msg::SawCut& c) {
  return fmt::format("{} CUT #{} at length {:.4f} m (saw counter before the cut {:.4f} m)", clock_text(c.stamp()),
                     c.cut_count(), c.length_in_force_m(), c.counter_before_cut_m());
}

}  // namespace lb::app
