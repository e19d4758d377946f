#pragma once
// What every device gateway is given: its bus loop and node, the DDS participant, its configuration.

#include <chrono>
#include <string>
#include <string_view>

#include "canopen/bus_loop.hpp"
#include "canopen/cycle_deadline.hpp"
#include "canopen/remote_node.hpp"
#include "canopen/sdo_client.hpp"
#include "canopen/sync_producer.hpp"
#include "dds/participant.hpp"
#include "gateways/persistence/set_value_store.hpp"
#include "profiles/line_config.hpp"

namespace lb::gateways {

struct DeviceContext {
  canopen::BusLoop& loop;
  canopen::RemoteNode& node;
  canopen::SyncProducer* sync;    // null on a monitor bus: the bridge produces no SYNC there
  canopen::SdoClient* sdo;        // null on a monitor bus: the bridge sends no SDO requests there
  canopen::CycleDeadline* cycle;  // status_publish per_cycle: the bus's SYNC cycle (PdoBurst); null: per_frame
  ddsl::Participant& dds;
  const std::string& line;
  const profiles::BusConfig& bus;
  const profiles::DeviceConfig& device;
  const profiles::Profile& profile;
  SetValueStore* set_values = nullptr;  // master role: where the set values in force are kept (null: nowhere)
  const profiles::StartupPolicy& startup;
  // Master role: no RPDO of this bus side goes out before this time (its start plus a momentary
  // command's hold). The run before it may have been killed in the middle of a press, and the
  // press it began must stay on the bus for its 100 ms: the first RPDO of this run ends it.
  std::chrono::steady_clock::time_point rpdos_from{};

  bool is_master() const { return profiles::masters(bus.role); }
  // The answer to a request (not a stop) while the bridge yields to another master on this bus.
  std::string another_master(std::string_view what) const {
    return "another master's SYNC runs on bus " + bus.name +
           ": the bridge transmits nothing but stops there until it is silent (diagnostics: "
           "yielding_to_other_master): " +
           std::string(what);
  }
  // The answer to a request the bus loop refused (BusLoop::try_post: too many waiting).
  std::string loop_busy(std::string_view what) const {
    return "bus " + bus.name + " is overloaded (" + std::to_string(canopen::BusLoop::kMaxPosted) +
           " requests wait for its loop): " + std::string(what) + " refused, not sent; ask again later";
  }
};

}  // namespace lb::gateways
