#pragma once
// Topic names follow ROS 2's DDS mapping: rt/<line>/<device>/<topic>.

#include <string>
#include <string_view>

namespace lb::ddsl {

inline std::string topic_name(std::string_view line, std::string_view device, std::string_view topic) {
  std::string name = "rt/";
  name.append(line).append("/").append(device).append("/").append(topic);
  return name;
}

}  // namespace lb::ddsl
