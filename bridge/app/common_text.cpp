#include "app/common_text.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <ctime>
#include <string>
#include <string_view>
#include <vector>

#include "app/nmt_text.hpp"

namespace lb::app {

namespace msg = linebridge_msgs::msg;

std::string to_text(msg::NmtState s) { return std::string(nmt_text(s)); }

std::string clock_text(const msg::Time& t) {
  const std::time_t secs = t.sec();
  std::tm tm{};
  localtime_r(&secs, &tm);
  return fmt::format("{:02}:{:02}:{:02}.{:03}", tm.tm_hour, tm.tm_min, tm.tm_sec, t.nanosec() / 1'000'000);
}

std::string state_text(const msg::DeviceHealth& h) {
  return fmt::format("{:<15} {:<7}", to_text(h.nmt_state()), h.online() ? "online" : "OFFLINE");
}

std::string errors_text(const msg::DeviceHealth& h) {
  std::string out;
  if (!h.active_errors().empty()) out = fmt::format(" | EMCY active: {:04X}", fmt::join(h.active_errors(), " "));
  if (!h.active_errors_known())
    out += " | active errors UNCERTAIN: " + h.active_errors_note();
  else if (!h.active_errors_note().empty())
    out += " | " + h.active_errors_note();  // e.g. an EMCY the device's own 1001h contradicted
  return out;
}

std::string other_values_text(const std::vector<msg::ProcessValue>& values) {
  if (values.empty()) return "";
  std::vector<std::string> parts;
  parts.reserve(values.size());
  for (const auto& v : values) {
    parts.push_back(fmt::format("{} {}{}{} ({}, raw {})", v.name(), v.value(), v.unit().empty() ? "" : " ", v.unit(),
                                v.pdo(), v.raw()));
  }
  return fmt::format(" | other: {}", fmt::join(parts, ", "));
}

std::string to_text(const msg::Emergency& e) {
  return fmt::format("{} EMCY {:04X}h ({}), error register {:02X}h, manufacturer [{:02X}], active: [{:04X}]{}",
                     clock_text(e.stamp()), e.error_code(), e.family(), e.error_register(),
                     fmt::join(e.manufacturer(), " "), fmt::join(e.active_errors(), " "),
                     e.active_errors_known() ? "" : " UNCERTAIN: " + e.active_errors_note());
}

std::string to_text(const msg::DeviceInfo& i) {
  std::string out = fmt::format(
      "{} node {}: {}\n  \"{}\" device type {:08X}h (profile {}{}), vendor {:08X}h, product {:08X}h, revision {:08X}h, "
      "serial {:08X}h, hardware \"{}\", software \"{}\", heartbeat {}\n",
      clock_text(i.stamp()), i.node_id(), i.started() ? "STARTED" : "NOT STARTED: " + to_text(i.boot_error()),
      i.device_name(), i.device_type(), i.profile_number(), i.profile_matches() ? "" : ", NOT the configured one",
      i.vendor_id(), i.product_code(), i.revision_number(), i.serial_number(), i.hardware_version(),
      i.software_version(),
      i.heartbeat_producer_ms() < 0 ? std::string("unknown") : fmt::format("{} ms", i.heartbeat_producer_ms()));
  for (const auto& p : i.pdos()) {
    std::vector<std::string> entries;
    for (auto e : p.mapping()) entries.push_back(fmt::format("{:08X}h", e));
    out += fmt::format("  {:<6} COB-ID {:08X}h type {:>3} inhibit {} x 100 us event {} ms mapping [{}]{}\n", p.name(),
                       p.cob_id(), p.transmission_type(), p.inhibit_time_100us(), p.event_timer_ms(),
                       fmt::join(entries, " "), p.adopted() ? " (the device's own, pdo_config: adopt)" : "");
  }
  const auto& w = i.configuration_word();
  if (w.read()) {
    std::vector<std::string> flags;
    for (const auto& f : w.flags()) flags.push_back(fmt::format("{}{}", f.on() ? "+" : "-", f.name()));
    out += fmt::format("  configuration word 6010h {:08X}h: {}\n", w.raw(), fmt::join(flags, " "));
  } else if (!w.remark().empty()) {
    out += "  configuration word: " + w.remark() + "\n";
  }
  if (i.error_history_read()) {
    // The code alone unless the device put additional information in bits 16..31.
    std::vector<std::string> entries;
    for (const auto e : i.error_history())
      entries.push_back(e > 0xFFFF ? fmt::format("{:08X}h", e) : fmt::format("{:04X}h", e));
    out += fmt::format("  error history 1003h (not the active errors; {} recorded, newest first): [{}]\n",
                       i.error_history_count(), fmt::join(entries, " "));
  } else if (!i.error_history_remark().empty()) {
    out += "  error history 1003h: " + i.error_history_remark() + "\n";
  }
  if (!i.remarks().empty()) out += "  " + i.remarks() + "\n";
  return out;
}

std::string to_text(const msg::BootError& e) {
  if (e.code().empty() && e.message().empty()) return "";
  return fmt::format("{}{}{}", e.code().empty() ? "" : "CiA 302-2 error " + e.code() + ": ", e.message(),
                     e.abort_code() != 0 ? fmt::format(" [abort {:08X}h]", e.abort_code()) : "");
}

namespace {

std::string yes_no(bool b) { return b ? "yes" : "no"; }
std::string or_dash(const std::string& s) { return s.empty() ? "-" : s; }

// A histogram as count, mean and its buckets (upper bound: observations at most that bound).
std::string histogram_text(const msg::Histogram& h, double unit, std::string_view unit_name) {
  if (h.count() == 0) return "none";
  std::string out = fmt::format("n {} mean {:.3f} {}", h.count(), h.sum() / static_cast<double>(h.count()) / unit,
                                unit_name);
  const auto n = std::min(h.upper_bounds().size(), h.cumulative_counts().size());
  for (std::size_t i = 0; i < n; ++i) {
    out += fmt::format(" <={:g}:{}", h.upper_bounds()[i] / unit, h.cumulative_counts()[i]);
  }
  return out;
}

// The names whose count is not zero, "name count" each; "none" when all are.
std::string counts_text(const std::vector<msg::NamedCount>& counts) {
  std::string out;
  for (const auto& c : counts) {
    if (c.count() == 0) continue;
    out += fmt::format("{}{} {}", out.empty() ? "" : ", ", c.name(), c.count());
  }
  return out.empty() ? "none" : out;
}

std::string codes_text(const std::vector<std::uint16_t>& codes) {
  if (codes.empty()) return "none";
  std::string out;
  for (const auto c : codes) out += fmt::format("{}{:04X}h", out.empty() ? "" : " ", c);
  return out;
}

}  // namespace

// Every field of the message, each under its IDL name (underscores as hyphens), so that nothing
// the bridge reports is hidden from an operator: Cli.DiagnosticsTextShowsEveryIdlField reads
// idl/common.idl and fails for a field this does not print.
std::string to_text(const msg::Diagnostics& d) {
  std::string out = fmt::format("{} line {} bridge-incarnation {:016x} commands-lost {} log-lines-dropped {}\n",
                                clock_text(d.stamp()), d.line(), d.bridge_incarnation(), d.commands_lost(),
                                d.log_lines_dropped());
  out += fmt::format("  set-value-store: {}\n", or_dash(d.set_value_store()));
  const auto& side = d.dds_side();
  out += fmt::format(
      "  dds-side: connected {} connects {} samples-dropped {} samples-not-forwarded {} samples-on-lanes {} "
      "remote-participants {} remote-participants-refused {} samples-sent {} samples-replaced {}{}\n",
      yes_no(side.connected()), side.connects(), side.samples_dropped(), side.samples_not_forwarded(),
      side.samples_on_lanes(), side.remote_participants(), side.remote_participants_refused(), side.samples_sent(),
      side.samples_replaced(), side.connects() != 0 && !side.connected() ? "  (the DDS process is NOT CONNECTED)" : "");
  out += fmt::format("  dds-side: peers-refused {} absent-s {:.1f} absent-alarm {} absent-alarms {} last-end {}\n",
                     side.peers_refused(), side.absent_s(), side.absent_alarm() ? "YES" : "no", side.absent_alarms(),
                     or_dash(side.last_end()));
  for (const auto& b : d.buses()) {
    out += fmt::format("  bus {:<12} {:<28} {:<7} {:<13} frames-in {:>9} ({:7.1f}/s) frames-out {:>9} ({:7.1f}/s) "
                       "load {} error-frames {} tx-dropped {}\n",
                       b.name(), b.interface_uri(), b.role(), b.state(), b.frames_in(), b.frames_in_per_s(),
                       b.frames_out(), b.frames_out_per_s(),
                       b.load_percent() < 0 ? std::string("n/a (fast replay)")
                                            : fmt::format("{:5.1f} %", b.load_percent()),
                       b.error_frames(), b.tx_dropped());
    out +=
        fmt::format("  bus {:<12} TEC {} REC {} bus-offs {} rx-overflows {} rx-dropped {} tx-queue-full {} reopens {} "
                    "record-errors {} replay {}{}\n",
                    b.name(), b.tx_error_counter(), b.rx_error_counter(), b.bus_offs(), b.rx_overflows(),
                    b.rx_dropped(), b.tx_queue_full(), b.reopens(), b.record_errors(), yes_no(b.replay()),
                    b.replay() ? " (heartbeat ages on the recording's clock)" : "");
    out +=
        fmt::format("  bus {:<12} handler-failures {} handlers-disabled {} frames-unclaimed {} requests-refused {}{}\n",
                    b.name(), b.handler_failures(), b.handlers_disabled(), b.frames_unclaimed(), b.requests_refused(),
                    b.requests_refused() != 0 ? " (loop overloaded)" : "");
    out += fmt::format(
        "  bus {:<12} other-master-frames {} yielding-to-other-master {} other-master-yields {} frames-held {} "
        "stops-sent-while-held {} other-master-last {}{}\n",
        b.name(), b.other_master_frames(), b.yielding_to_other_master() ? "YES" : "no", b.other_master_yields(),
        b.frames_held(), b.stops_sent_while_held(), or_dash(b.other_master_last()),
        b.yielding_to_other_master() ? " (YIELDING: transmits only stops, refuses other set values and commands)" : "");
    out += fmt::format("  bus {:<12} takeover {}\n", b.name(), or_dash(b.takeover()));
    out += fmt::format("  bus {:<12} sync-period-s {} sync-period-deviation-s {}\n", b.name(),
                       b.sync_period_s() > 0 ? fmt::format("{:g}", b.sync_period_s()) : std::string("none"),
                       histogram_text(b.sync_period_deviation_s(), 1e-3, "ms"));
    out += fmt::format("  bus {:<12} mandatory-missing {} mandatory-state {}\n", b.name(),
                       b.mandatory_missing().empty() ? std::string("none")
                                                     : fmt::format("{}", fmt::join(b.mandatory_missing(), ", ")),
                       or_dash(b.mandatory_state()));
  }
  for (const auto& n : d.nodes()) {
    out += fmt::format("  {:<12} {:<10} node {:>3}{} {:<7} {:<15} node-state {} boot-state {}\n", n.device(), n.bus(),
                       n.node_id(), n.mandatory() ? " (mandatory)" : "", n.online() ? "online" : "OFFLINE",
                       to_text(n.nmt_state()), or_dash(n.node_state()), or_dash(n.boot_state()));
    out += fmt::format("  {:<12} last-heartbeat-age {} boot-ups {} boots {} boot-failures {} state-unknown {} "
                       "boot-ups-not-believed {} pdos-received {} pdos-sent {} pdo-length-errors {} emergencies {} "
                       "range-warnings {} malformed-emergencies {} malformed-heartbeats {}\n",
                       "",
                       n.last_heartbeat_age_s() < 0 ? std::string("never")
                                                    : fmt::format("{:.2f} s", n.last_heartbeat_age_s()),
                       n.boot_ups(), n.boots(), n.boot_failures(), n.state_unknown(), n.boot_ups_not_believed(),
                       n.pdos_received(), n.pdos_sent(), n.pdo_length_errors(), n.emergencies(), n.range_warnings(),
                       n.malformed_emergencies(), n.malformed_heartbeats());
    out += fmt::format("  {:<12} states-not-believed {} heartbeats-missing-while-heard {} "
                       "heartbeat-producer-rewrites {} heartbeat-judgements-deferred {} resets-spared {}\n",
                       "", n.states_not_believed(), n.heartbeats_missing_while_heard(), n.heartbeat_producer_rewrites(),
                       n.heartbeat_judgements_deferred(), n.resets_spared());
    out += fmt::format("  {:<12} mandatory {} line-hold {} boot-error {}\n", "", yes_no(n.mandatory()),
                       or_dash(n.line_hold()), or_dash(to_text(n.boot_error())));
    out += fmt::format("  {:<12} set-values-at-start {}\n", "", or_dash(n.set_values_at_start()));
    out += fmt::format("  {:<12} device-type {} profile {} product-name {} last-boot-passed {} adopted {}\n", "",
                       or_dash(n.device_type()), or_dash(n.profile()), or_dash(n.product_name()),
                       yes_no(n.last_boot_passed()), yes_no(n.adopted()));
    out +=
        fmt::format("  {:<12} error-register {:02X}h active-errors {} active-errors-known {} active-errors-note {}\n",
                    "", n.error_register(), codes_text(n.active_errors()), yes_no(n.active_errors_known()),
                    or_dash(n.active_errors_note()));
    out += fmt::format("  {:<12} boot-failures-by-letter {} emergencies-by-class {}\n", "",
                       counts_text(n.boot_failures_by_letter()), counts_text(n.emergencies_by_class()));
    out += fmt::format("  {:<12} sdo-duration-s {}\n", "", histogram_text(n.sdo_duration_s(), 1e-3, "ms"));
  }
  return out;
}

}  // namespace lb::app
