#include "app/common_text.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "app/saw_text.hpp"

namespace lb::app {

namespace msg = linebridge_msgs::msg;

std::string to_text(const msg::Emergency& e) {
  return fmt::format("{} EMCY {:04X}h ({}), error register {:02X}h, manufacturer [{:02X}], active: [{:04X}]",
                     clock_text(e.stamp()), e.error_code(), e.family(), e.error_register(),
                     fmt::join(e.manufacturer(), " "), fmt::join(e.active_errors(), " "));
}

std::string to_text(const msg::DeviceInfo& i) {
  return fmt::format(
      "{} node {}: \"{}\" device type {:08X}h (profile {}{}), vendor {:08X}h, product {:08X}h, revision {:08X}h, "
      "serial {:08X}h, hardware \"{}\", software \"{}\"{}",
      clock_text(i.stamp()), i.node_id(), i.device_name(), i.device_type(), i.profile_number(),
      i.profile_matches() ? "" : ", NOT the configured one", i.vendor_id(), i.product_code(), i.revision_number(),
      i.serial_number(), i.hardware_version(), i.software_version(), i.remarks().empty() ? "" : " | " + i.remarks());
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
  }
  return out;
}

}  // namespace lb::app
