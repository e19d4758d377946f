#include "app/drive_text.hpp"

#include <fmt/format.h>

#include "app/common_text.hpp"

namespace lb::app {

namespace msg = linebridge_msgs::msg;

namespace {

// What both drives print alike: values, status word, set values in force, faults.
template <class Status>
std::string drive_text(const Status& s, const std::string& status_bits, const std::string& extra_status,
                       const std::string& pressed) {
  return fmt::format(
      "{} {} | speed {:7.2f} % (echo {:7.2f} %) load {:6.2f} % product {:8.3f} m/min | status {:04X}h [{}]{} | "
      "set: extruder {}, speed {:.2f} %{}{}{}{}{}{}",
      clock_text(s.stamp()), state_text(s.health()), s.speed_actual_percent(), s.speed_set_echo_percent(),
      s.load_actual_percent(), s.product_speed_m_per_min(), s.status_word().raw(), status_bits, extra_status,
      s.control_word().extruder_running() ? "running" : "stopped", s.speed_set_percent(),
      pressed.empty() ? "" : ", pressed [" + pressed + "]", s.set_echo_mismatch() ? " | SET ECHO MISMATCH" : "",
      s.manufacturer_status_word_present()
          ? fmt::format(" | manufacturer status word {:04X}h", s.manufacturer_status_word())
          : "",
      s.pdo_length_errors() ? fmt::format(" | {} short PDOs", s.pdo_length_errors()) : "", errors_text(s.health()),
      other_values_text(s.other_values()));
}

// Functions f1..f3: the same bits in both drives' words, after their own ones.
template <class StatusWord>
std::string status_text(const StatusWord& w, std::initializer_list<std::pair<bool, const char*>> own) {
  std::string out = flags_text(own);
  const auto f = flags_text({{w.fault(), "FAULT"},
                             {w.alarm(), "ALARM"},
                             {w.increase_request(), "increase-request"},
                             {w.decrease_request(), "decrease-request"},
                             {w.f1_running(), "f1-running"},
                             {w.f2_running(), "f2-running"},
                             {w.f3_running(), "f3-running"}});
  return out.empty() || f.empty() ? out + f : out + " " + f;
}

template <class ControlWord>
std::string pressed_text(const ControlWord& c, std::initializer_list<std::pair<bool, const char*>> own) {
  std::string out = flags_text(own);
  const auto f = flags_text({{c.f1_stop(), "f1_stop"},
                             {c.f1_start(), "f1_start"},
                             {c.f2_stop(), "f2_stop"},
                             {c.f2_start(), "f2_start"},
                             {c.f3_stop(), "f3_stop"},
                             {c.f3_start(), "f3_start"}});
  return out.empty() || f.empty() ? out + f : out + " " + f;
}

}  // namespace

std::string to_text(msg::PullerSpeedSetMode m) {
  switch (m) {
    case msg::PULLER_SPEED_SET_LOCAL: return "local";
    case msg::PULLER_SPEED_SET_REMOTE: return "remote";
    case msg::PULLER_SPEED_SET_NOT_REPORTED: break;
  }
  return "not reported";
}

std::string to_text(const msg::PullerStatus& s) {
  const auto& w = s.status_word();
  const auto& c = s.control_word();
  return drive_text(s,
                    status_text(w, {{w.motor_running(), "running"},
                                    {w.motor_ready_to_start(), "ready"},
                                    {w.clamp_closed(), "clamp-closed"},
                                    {w.reverse_direction(), "reverse"}}),
                    w.speed_set_mode() == msg::PULLER_SPEED_SET_NOT_REPORTED
                        ? ""
                        : " speed set mode " + to_text(w.speed_set_mode()),
                    pressed_text(c, {{c.motor_stop(), "motor_stop"},
                                     {c.motor_start(), "motor_start"},
                                     {c.clamp_close(), "clamp_close"},
                                     {c.clamp_open(), "clamp_open"}}));
}

std::string to_text(const msg::CorrugatorStatus& s) {
  const auto& w = s.status_word();
  const auto& c = s.control_word();
  return drive_text(s,
                    status_text(w, {{w.drive_running(), "running"},
                                    {w.drive_ready_to_start(), "ready"},
                                    {w.master_extruder_enabled(), "extruder-enabled"},
                                    {w.start_cut_pulse(), "CUT-PULSE"}}),
                    "",
                    pressed_text(c, {{c.drive_stop(), "drive_stop"},
                                     {c.drive_start(), "drive_start"},
                                     {c.move_in(), "move_in"},
                                     {c.move_out(), "move_out"}}));
}

}  // namespace lb::app
