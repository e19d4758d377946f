#pragma once
// linebridge-cli echo: a device's topic (or the bridge's diagnostics) as readable lines, whatever
// the device type. Says so on stderr while no bridge publishes the topic.

#include <string>

#include "dds/participant.hpp"
#include "profiles/line_config.hpp"

namespace lb::app {

struct EchoOptions {
  std::string topic = "status";
  double rate_hz = 2;     // status lines per second at most (a change of status bits or online always shows)
  double duration_s = 0;  // 0: until Ctrl-C
};

// The topics `echo` knows for a device type (a registry name, profiles/device_types.hpp, or "bridge").
std::string echo_topics(const std::string& device_type);

// Returns the exit code (cli_exit.hpp).
int run_echo(ddsl::Participant& dds, const std::string& line, const std::string& device, const std::string& device_type,
             const EchoOptions& options);

}  // namespace lb::app
