#pragma once
// Brings one device into service (master role), at start-up and after every boot-up:
//   1. read 1000h device type: is anyone there?
//   2. the SDO writes of its configuration, in order;
//   3. NMT start;
//   4. read its identity (1018h, 1008h/1009h/100Ah) and report it.
// All steps are asynchronous on the bus loop, so a device that does not answer delays nobody else;
// it is reported and tried again after the retry interval. A new boot-up restarts the sequence.

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "canopen/bus_loop.hpp"
#include "canopen/object_value.hpp"
#include "canopen/remote_node.hpp"
#include "canopen/sdo_client.hpp"

namespace lb::canopen {

struct DeviceIdentity {
  std::uint32_t device_type = 0;
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision_number = 0;
  std::uint32_t serial_number = 0;
  std::string device_name;
  std::string hardware_version;
  std::string software_version;
  std::string remarks;  // optional objects the device did not provide
  std::int64_t read_at_ns = 0;
};

class BootSequence {
 public:
  struct Write {
    std::uint16_t index;
    std::uint8_t sub;
    DataType type;
    ObjectValue value;
  };
  struct Listener {
    std::function<void(const std::string& state)> on_state;      // "configuring", "started", "not answering: ..."
    std::function<void(const DeviceIdentity&)> on_identity;
  };

  // Installs itself as the node's boot handler. Before the loop starts.
  BootSequence(BusLoop& loop, RemoteNode& node, SdoClient& sdo, std::vector<Write> writes,
               std::chrono::milliseconds retry_interval, Listener listener);

  const std::string& state() const { return state_; }  // loop thread

 private:
  void begin();
  void write_next(std::uint64_t generation, std::size_t i);
  void started(std::uint64_t generation);
  void read_identity(std::uint64_t generation, std::shared_ptr<DeviceIdentity> id, std::size_t step);
  void fail(std::uint64_t generation, const std::string& why);
  void set_state(std::string state);

  BusLoop& loop_;
  RemoteNode& node_;
  SdoClient& sdo_;
  std::vector<Write> writes_;
  std::chrono::milliseconds retry_interval_;
  Listener listener_;
  BusLoop::TimerId retry_timer_;
  std::uint64_t generation_ = 0;  // a restarted sequence makes the callbacks of the old one no-ops
  std::string state_ = "waiting";
};

}  // namespace lb::canopen
