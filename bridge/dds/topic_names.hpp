#pragma once
// Topic names follow ROS 2's DDS mapping: rt/<line>/<device>/<topic>.

#include <string>
#include <string_view>

namespace lb::ddsl {

// The bridge's own name space, where a device name would be: rt/<line>/bridge/diagnostics and the
// line-wide services <line>/bridge/<service>. No device may be called so (the configuration
// refuses it), or its topics would meet the bridge's.
inline constexpr std::string_view kBridgeNamespace = "bridge";

inline std::string topic_name(std::string_view line, std::string_view device, std::string_view topic) {
  std::string name = "rt/";
  name.append(line).append("/").append(device).append("/").append(topic);
  return name;
}

// A device's status topic (rt/<line>/<device>/status): what tells an application the device is
// there, so a new DDS side of the bus process creates these writers first.
inline bool is_status_topic(std::string_view topic) { return topic.ends_with("/status"); }

// "<line>/bridge/<service>": the path of a line-wide service for ServiceServer / ServiceClient,
// which make rq/<path>Request and rr/<path>Reply of it.
inline std::string line_service_path(std::string_view line, std::string_view service) {
  std::string path(line);
  path.append("/").append(kBridgeNamespace).append("/").append(service);
  return path;
}

}  // namespace lb::ddsl
