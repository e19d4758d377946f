#pragma once
// rt/<line>/bridge/diagnostics: per bus frames, errors, state and load; per device online, NMT
// state, heartbeat age and counters. Each bus loop takes its own snapshot (its state is
// loop-thread only); a publishing thread merges the latest snapshots once per period.

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "canopen/active_master_watch.hpp"
#include "canopen/bus_loop.hpp"
#include "canopen/flying_master.hpp"
#include "canopen/other_master.hpp"
#include "canopen/remote_node.hpp"
#include "canopen/sdo_client.hpp"
#include "canopen/sync_producer.hpp"
#include "dds/participant.hpp"
#include "gateways/adapters/device_services.hpp"
#include "gateways/node/mandatory_devices.hpp"
#include "gateways/persistence/hold_keeper.hpp"
#include "link/pi_mutex.hpp"
#include "msgs/commonPubSubTypes.h"
#include "profiles/line_config.hpp"

namespace lb::gateways {

class DiagnosticsGateway {
 public:
  struct Device {
    const profiles::DeviceConfig* config;
    const canopen::RemoteNode* node;
    const DeviceServices* services;
    std::size_t index = 0;             // its place among the devices of its bus (MandatoryDevices' member)
    const HoldKeeper* hold = nullptr;  // master role, when holds are kept: its hold, from before a restart or not
  };
  struct Bus {
    const profiles::BusConfig* config;
    canopen::BusLoop* loop;
    const canopen::OtherMasterWatch* other_master;  // master role only
    std::vector<Device> devices;
    const MandatoryDevices* mandatory = nullptr;  // master or standby role, when a device of the bus is mandatory
    const canopen::ActiveMasterWatch* standby = nullptr;  // standby role
    const canopen::FlyingMaster* flying = nullptr;        // standby role: its negotiation
    const canopen::SyncProducer* sync = nullptr;          // master role: its SYNC's timing
    const canopen::SdoClient* sdo = nullptr;              // master role: its transfers' durations
  };

  // The process's own fields (the set-value store, the log), filled on the publishing thread.
  using BridgeFields = std::function<void(linebridge_msgs::msg::Diagnostics&)>;
  DiagnosticsGateway(ddsl::Participant& dds, const std::string& line, std::vector<Bus> buses,
                     BridgeFields bridge_fields = {}, std::chrono::milliseconds period = std::chrono::seconds(1));
  ~DiagnosticsGateway();
  DiagnosticsGateway(const DiagnosticsGateway&) = delete;
  DiagnosticsGateway& operator=(const DiagnosticsGateway&) = delete;

  void start();  // before the loops start: a first snapshot, the per-bus timers, and publishing (the first at once)
  void stop();

 private:
  struct Previous {
    std::chrono::steady_clock::time_point at{};
    std::uint64_t frames_in = 0, frames_out = 0, bits = 0;
  };
  void snapshot(std::size_t bus);  // on that bus's loop thread
  void publish_loop();

  const ddsl::Participant& dds_;
  std::string line_;
  std::vector<Bus> buses_;
  BridgeFields bridge_fields_;
  std::chrono::milliseconds period_;
  ddsl::Writer<linebridge_msgs::msg::DiagnosticsPubSubType> writer_;
  std::vector<Previous> previous_;  // per bus, loop thread of that bus

  // Taken by every bus loop (snapshot, realtime under SCHED_FIFO) and by the publishing thread
  // (normal priority) while it copies the snapshots: with priority inheritance, a publisher
  // preempted while holding it runs at the waiting loop's priority until it unlocks, instead of
  // holding the loop (and its SYNC) for as long as other normal-priority work runs.
  link::PiMutex mutex_;
  std::condition_variable_any cv_;  // waited on by the publishing thread only; the loops never notify
  bool stopping_ = false;
  std::vector<linebridge_msgs::msg::BusDiagnostics> bus_snapshots_;
  std::vector<std::vector<linebridge_msgs::msg::NodeDiagnostics>> node_snapshots_;
  std::thread thread_;
};

}  // namespace lb::gateways
