#pragma once
// The saw most end-to-end tests drive, as a devices: entry of a line file: saw1 at node 5 (CiA 420-4
// 3.1), simulated at 60 m/min at 100 % (one metre a second, 20 mm per 20 ms SYNC) with a 100 ms
// heartbeat the bridge gives up on after 400 ms.

#include <string>

namespace lb::test {

inline std::string simulated_saw(const std::string& bus) {
  return "  - name: saw1\n"
         "    bus: " +
         bus +
         "\n"
         "    node_id: 5\n"
         "    profile: cia420-4\n"
         "    version: '3.1'\n"
         "    heartbeat_timeout_ms: 400\n"
         "    simulation: {max_speed_m_per_min: 60, acceleration_m_per_min_s: 6000, heartbeat_period_ms: 100}\n";
}

}  // namespace lb::test
