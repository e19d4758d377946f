#pragma once
// The gateway process's core: from a line configuration, one bus loop per bus (with SYNC and NMT
// in the master role), one gateway per device, the line-wide device-management services, one DDS
// participant for all of them.

#include <atomic>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "app/service_notifier.hpp"
#include "canopen/active_master_watch.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/cycle_deadline.hpp"
#include "canopen/flying_master.hpp"
#include "canopen/heartbeat_producer.hpp"
#include "canopen/other_master.hpp"
#include "canopen/remote_node.hpp"
#include "canopen/sdo_client.hpp"
#include "canopen/sdo_server.hpp"
#include "canopen/sync_producer.hpp"
#include "dds/participant.hpp"
#include "gateways/adapters/device_services.hpp"
#include "gateways/adapters/diagnostics_gateway.hpp"
#include "gateways/adapters/gateway.hpp"
#include "gateways/node/mandatory_devices.hpp"
#include "gateways/persistence/hold_keeper.hpp"
#include "gateways/persistence/set_value_store.hpp"
#include "gateways/routing/management_services.hpp"
#include "profiles/line_config.hpp"

namespace lb::app {

// How a bus of the configuration is opened: for real (open_configured_bus: the medium, listen-only
// in the monitor role, recording), or as a stand-in that touches no CAN (linebridge --check).
using BusOpener = std::function<Result<std::unique_ptr<can::Bus>>(const profiles::BusConfig&)>;
Result<std::unique_ptr<can::Bus>> open_configured_bus(const profiles::BusConfig& bus);

class LineBridge {
 public:
  // Opens every bus and creates every gateway on `dds`, or fails with the reason; nothing runs yet.
  // The caller creates the participant (app/dds_options.hpp), so it can tell a security refusal
  // (a configuration error) from other start-up failures.
  static Result<std::unique_ptr<LineBridge>> create(const profiles::LineConfig& config,
                                                    std::unique_ptr<ddsl::Participant> dds,
                                                    const BusOpener& open_bus = open_configured_bus);
  LineBridge() = default;  // create() builds one
  ~LineBridge();
  LineBridge(const LineBridge&) = delete;
  LineBridge& operator=(const LineBridge&) = delete;

  // Before start(): called once, on a bus loop's thread, when the first standby bus takes over
  // (docs/redundancy.md); at once in start() when no bus stands by. The DDS side serves from then on.
  void on_mastering(std::function<void()> callback) { on_mastering_ = std::move(callback); }

  void start();
  void stop();  // idempotent
  // A bus loop failed for good (the process should end with an error and be restarted): its why.
  std::optional<std::string> failure() const;
  // A bus of this bridge lost a negotiation to another master (CiA 302-2) and asked the process to
  // stop: the caller restarts it as the standby it is configured to be (docs/redundancy.md).
  bool stepped_back() const { return stepped_back_.load(); }
  // Why the set values in force are not kept across restarts; empty when they are.
  const std::string& set_value_store_problem() const { return store_problem_; }

  // Every bus loop's progress, for the service watchdog (each loop wakes at least every
  // ServiceNotifier::kLoopTick, so an idle bus still shows progress).
  std::vector<ServiceNotifier::Loop> watched_loops() const;
  const ddsl::Participant& dds() const { return *dds_; }

 private:
  struct BusRuntime {
    const profiles::BusConfig* config;
    std::unique_ptr<canopen::BusLoop> loop;
    std::unique_ptr<canopen::SyncProducer> sync;
    // status_publish per_cycle: the SYNC cycle its devices' status samples wait for (PdoBurst).
    std::unique_ptr<canopen::CycleDeadline> cycle;
    std::unique_ptr<canopen::HeartbeatProducer> heartbeat;
    std::unique_ptr<canopen::SdoClient> sdo;
    std::unique_ptr<canopen::OtherMasterWatch> other_master;
    // Standby role: the watch on the master's heartbeat, and what the bus continues at a takeover.
    std::unique_ptr<canopen::ActiveMasterWatch> standby;
    // Standby role: the CiA 302-2 negotiation of who masters the bus.
    std::unique_ptr<canopen::FlyingMaster> flying;
    // The bridge's own object dictionary (1F80h, 1F90h...), served on master_node_id while it masters.
    std::unique_ptr<canopen::SdoServer> own_dictionary;
    std::vector<std::unique_ptr<canopen::RemoteNode>> nodes;
    std::vector<std::unique_ptr<gateways::DeviceServices>> services;
    std::vector<std::unique_ptr<gateways::Gateway>> gateways;
    // Master or standby role, when a device of the bus is mandatory: the line-level policy for them.
    std::unique_ptr<gateways::MandatoryDevices> mandatory;
    // Master role, when the state directory is usable: per device (bus order), its hold kept across restarts.
    std::vector<std::unique_ptr<gateways::HoldKeeper>> holds;
    std::uint32_t lane = 0;  // over the channel: the lane its devices' readers use (0: none)
  };

  // Before the buses: their gateways keep set values in it until they are gone.
  std::unique_ptr<gateways::SetValueStore> set_values_;
  std::string store_problem_;  // why set values are not kept, when they are not
  std::unique_ptr<ddsl::Participant> dds_;
  std::vector<BusRuntime> buses_;
  // The line-wide nmt/sdo/command/parameter services; they call into the buses' device handlers,
  // and the participant (reset first in the destructor) stops calling them before anything goes.
  std::unique_ptr<gateways::ManagementServices> management_;
  std::unique_ptr<gateways::DiagnosticsGateway> diagnostics_;
  static void start_master(BusRuntime& rt);
  void take_over(BusRuntime& rt, const canopen::ActiveMasterWatch::Takeover& t);
  void step_back(BusRuntime& rt, const std::string& why);
  void mastering();  // a bus masters: the first time, on_mastering_

  std::function<void()> on_mastering_;
  std::once_flag mastering_once_;
  mutable std::mutex failure_mutex_;
  std::optional<std::string> failure_;
  std::atomic<bool> stepped_back_{false};
};

}  // namespace lb::app
