#pragma once
// linebridge-cli's service calls: nmt, sdo-read, sdo-write, param get/set, command, and a feeder
// box's typed services. Each prints the bridge's answer and returns the process exit code
// (cli_exit.hpp: 0 done, 1 refused, 3 no answer). The management services are line-wide
// (<line>/bridge/<service>, the request names the device); a feeder box's are its own
// (<line>/<device>/<service>).

#include <chrono>
#include <optional>
#include <string>
#include <vector>

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

int call_feeder_command(const ServiceTarget& t, unsigned feeder, const std::string& command,
                        unsigned manufacturer_code);
int call_feeder_test(const ServiceTarget& t, unsigned feeder, const std::string& test, unsigned parameter);
// settings: FUNCTION=STATE, e.g. yarn_break_sensor=active.
int call_feeder_functions(const ServiceTarget& t, unsigned feeder, const std::vector<std::string>& settings);
int call_feeder_assignment(const ServiceTarget& t, unsigned feeder, std::optional<unsigned> number,
                           std::optional<unsigned> color);
int call_weft_insertion_type(const ServiceTarget& t, const std::string& type);
int call_trigger_source(const ServiceTarget& t, const std::vector<std::string>& selected);

}  // namespace lb::app
