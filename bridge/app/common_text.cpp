#include "app/common_text.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <string>
#include <vector>

#include "app/saw_text.hpp"

namespace lb::app {

namespace msg = linebridge_msgs::msg;

std::string to_text(const msg::Emergency& e) {
  return fmt::format("{} EMCY {:04X}h ({}), error register {:02X}h, manufacturer [{:02X}], active: [{:04X}]",
                     clock_text(e.stamp()), e.error_code(), e.family(), e.error_register(),
                     fmt::join(e.manufacturer(), " "), fmt::join(e.active_errors(), " "));
}

std::string to_text(const msg::DeviceInfo& i) {
  std::string out = fmt::format(
      "{} node {}: {}\n  \"{}\" device type {:08X}h (profile {}{}), vendor {:08X}h, product {:08X}h, revision {:08X}h, "
      "serial {:08X}h, hardware \"{}\", software \"{}\", heartbeat {}\n",
      clock_text(i.stamp()), i.node_id(),
      i.started() ? "STARTED" : "NOT STARTED: " + to_text(i.boot_error()), i.device_name(), i.device_type(),
      i.profile_number(), i.profile_matches() ? "" : ", NOT the configured one", i.vendor_id(), i.product_code(),
      i.revision_number(), i.serial_number(), i.hardware_version(), i.software_version(),
      i.heartbeat_producer_ms() < 0 ? std::string("unknown") : fmt::format("{} ms", i.heartbeat_producer_ms()));
  for (const auto& p : i.pdos()) {
    std::vector<std::string> entries;
    for (auto e : p.mapping()) entries.push_back(fmt::format("{:08X}h", e));
    out += fmt::format("  {:<6} COB-ID {:08X}h type {:>3} inhibit {} x 100 us event {} ms mapping [{}]{}\n", p.name(),
                       p.cob_id(), p.transmission_type(), p.inhibit_time_100us(), p.event_timer_ms(),
                       fmt::join(entries, " "), p.adopted() ? " (the device's own, pdo_config: adopt)" : "");
  }
  if (!i.remarks().empty()) out += "  " + i.remarks() + "\n";
  return out;
}

std::string to_text(const msg::BootError& e) {
  if (e.code().empty() && e.message().empty()) return "";
  return fmt::format("{}{}{}", e.code().empty() ? "" : "CiA 302-2 error " + e.code() + ": ", e.message(),
                     e.abort_code() != 0 ? fmt::format(" [abort {:08X}h]", e.abort_code()) : "");
}

std::string to_text(const msg::Diagnostics& d) {
  std::string out = fmt::format("{} line {}\n", clock_text(d.stamp()), d.line());
  for (const auto& b : d.buses()) {
    out += fmt::format("  bus {:<12} {:<28} {:<7} {:<13} in {:>9} ({:7.1f}/s) out {:>9} ({:7.1f}/s) load {:5.1f} % "
                       "errors {} dropped {}\n",
                       b.name(), b.interface_uri(), b.role(), b.state(), b.frames_in(), b.frames_in_per_s(), b.frames_out(),
                       b.frames_out_per_s(), b.load_percent(), b.error_frames(), b.tx_dropped());
  }
  for (const auto& n : d.nodes()) {
    out += fmt::format("  {:<12} {:<10} node {:>3} {:<7} {:<15} heartbeat {:>6} boots {} PDOs in {} out {} short {} "
                       "EMCY {} | {}\n",
                       n.device(), n.bus(), n.node_id(), n.online() ? "online" : "OFFLINE", to_text(n.nmt_state()),
                       n.last_heartbeat_age_s() < 0 ? std::string("never") : fmt::format("{:.2f} s", n.last_heartbeat_age_s()),
                       n.boot_ups(), n.pdos_received(), n.pdos_sent(), n.pdo_length_errors(), n.emergencies(), n.boot_state());
    if (!n.boot_error().code().empty() && n.boot_state().rfind("failed", 0) != 0) {
      out += fmt::format("  {:<12} last boot failure: {}\n", "", to_text(n.boot_error()));
    }
  }
  return out;
}

}  // namespace lb::app
