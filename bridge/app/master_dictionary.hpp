#pragma once
// The bridge's own object dictionary on a bus it masters (node master_node_id), read over SDO like a
// device's: what CiA 302 says a master is (1F80h NMT start-up) and, on a standby bus, the CiA 302-2
// flying-master timing it negotiates with (1F90h), so that a service tool or the other master's
// integrator can check them on the running line. Read-only: the line file is where they change.

#include "canopen/sdo_server.hpp"
#include "profiles/line_config.hpp"

namespace lb::app {

// 1000h device type (0: no device profile), 1001h error register, 1017h producer heartbeat time,
// 1F80h (bit 0 NMT master; bit 5 flying master on a standby bus), 1F90h sub 0..6 on a standby bus.
canopen::ObjectDictionary master_dictionary(const profiles::BusConfig& bus);

}  // namespace lb::app
