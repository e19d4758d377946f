#pragma once
// The line file of a DDS Security test line: a dds: section (local host only) with the security
// block TestPki::security_yaml() gives (empty for the plain file pki.sh init reads), one master bus
// `ext` with a 20 ms SYNC, and the devices given (YAML list items, indented by two).

#include <cstdint>
#include <string>

namespace lb::test {

inline std::string secured_line_yaml(const std::string& line, std::uint32_t domain, const std::string& security,
                                     const std::string& bus_uri, const std::string& devices) {
  return "line: " + line + "\ndds:\n  domain: " + std::to_string(domain) + "\n  localhost_only: true\n" + security +
         "buses:\n  - {name: ext, interface: '" + bus_uri + "', role: master, sync_period_ms: 20}\ndevices:\n" +
         devices;
}

}  // namespace lb::test
