#pragma once
// linebridge-cli's service calls: nmt, sdo-read, sdo-write, param get/set, command. Each prints the
// bridge's answer and returns the process exit code (0 success, 1 refused or failed). The services
// are line-wide (<line>/bridge/<service>); the request names the device.

#include <chrono>
#include <string>

#include "dds/participant.hpp"

namespace lb::app {

struct ServiceTarget {
  ddsl::Participant& dds;
  std::string line;
  std::string device;
  std::chrono::milliseconds timeout;
};

int call_nmt(const ServiceTarget& t, const std::string& command);
int call_sdo_read(const ServiceTarget& t, std::uint16_t index, std::uint8_t sub, const std::string& type);
int call_sdo_write(const ServiceTarget& t, std::uint16_t index, std::uint8_t sub, const std::string& type,
                   const std::string& value);
int call_get_parameter(const ServiceTarget& t, const std::string& name);
int call_set_parameter(const ServiceTarget& t, const std::string& name, double value);
int call_command(const ServiceTarget& t, const std::string& name);
// Reads 1000h and 1018h sub 1..4 and prints them as the `identity:` lines of the device's entry in
// a line file, so an integrator pins the device at hand.
int call_identity(const ServiceTarget& t);

}  // namespace lb::app
