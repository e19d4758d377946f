#pragma once
// What every device offers on DDS whatever its profile: its emergencies, its identity (info), and
// the nmt, sdo_read, sdo_write, get_parameter and set_parameter services (the last two: profile
// objects by name, in engineering units, checked against the profile's access and range). In the master role it also owns the device's boot
// sequence (presence check, SDO configuration, NMT start, identity).
// Device-type gateways add status, set values and typed configuration.

#include <functional>
#include <memory>
#include <string>

#include "canopen/boot_sequence.hpp"
#include "gateways/device_context.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

class DeviceServices {
 public:
  // Throws std::runtime_error at start-up when a topic cannot be created.
  explicit DeviceServices(DeviceContext context);
  DeviceServices(const DeviceServices&) = delete;
  DeviceServices& operator=(const DeviceServices&) = delete;

  // "started", "not answering: ...", "monitored" (monitor role): loop thread.
  std::string boot_state() const { return boot_ ? boot_->state() : "monitored"; }

 private:
  using Reply = std::function<void(bool ok, std::uint32_t abort_code, std::string message)>;
  void on_nmt(const linebridge_msgs::srv::Nmt_Request& request, std::function<void(bool, std::string)> reply);
  std::string refusal() const;  // why this bus takes no commands, or empty
  void serve_parameters(const std::string& path);  // get_parameter / set_parameter
  void publish_info(const canopen::DeviceIdentity& id);

  DeviceContext ctx_;
  ddsl::Writer<linebridge_msgs::msg::EmergencyPubSubType> emergency_writer_;
  ddsl::Writer<linebridge_msgs::msg::DeviceInfoPubSubType> info_writer_;
  std::unique_ptr<canopen::BootSequence> boot_;
};

}  // namespace lb::gateways
