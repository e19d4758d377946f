#pragma once
// The line-wide device-management services: nmt, sdo_read, sdo_write, command, get_parameter and
// set_parameter, served once per bridge on rq/<line>/bridge/<service>Request and
// rr/<line>/bridge/<service>Reply. Every request names its device in its first field; this router
// hands it to that device's handler (DeviceServices, or its gateway's CommandService), which does
// the work for its device as before, on its own bus loop.
//
// Why line-wide rather than per device: Fast DDS costs ~22 KiB per DataWriter, ~18 KiB per
// DataReader and ~1.5 KiB per topic whatever the QoS. Six services per device were 12 of a saw's
// 18 endpoints and 12 of its 18 topics: ~260 KiB per device, ~60 MiB of the ~120 MiB a bridge
// with 8 buses x 30 saws used. Line-wide they are 12 endpoints per bridge.

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

class CommandService;
class DeviceServices;

class ManagementServices {
 public:
  struct Device {
    std::string name;                // as in the configuration and the requests
    std::string kind;                // for refusals, e.g. "feeder, cia414-2 1.1"
    DeviceServices* services;        // nmt, sdo_read, sdo_write, get_parameter, set_parameter
    const CommandService* commands;  // null: the device type has no momentary commands
  };

  // Routes to devices (in configuration order; names unique) without serving anything: tests use
  // it directly. The handlers must outlive the router.
  ManagementServices(std::string line, std::vector<Device> devices);
  ManagementServices(const ManagementServices&) = delete;
  ManagementServices& operator=(const ManagementServices&) = delete;

  // The router serving the six services on dds; errors only at start-up. Create it after every
  // device, and let the participant go (no more requests) before the devices do.
  static Result<std::unique_ptr<ManagementServices>> serve(ddsl::Participant& dds, const std::string& line,
                                                           std::vector<Device> devices);

  // One request each, on the thread that received it (a Fast DDS thread); refused at once when
  // the request names no device of this line, else as its device's handler answers.
  void nmt(const linebridge_msgs::srv::Nmt_Request& request,
           ddsl::Respond<linebridge_msgs::srv::Nmt_Response> respond) const;
  void sdo_read(const linebridge_msgs::srv::SdoRead_Request& request,
                ddsl::Respond<linebridge_msgs::srv::SdoRead_Response> respond) const;
  void sdo_write(const linebridge_msgs::srv::SdoWrite_Request& request,
                 ddsl::Respond<linebridge_msgs::srv::SdoWrite_Response> respond) const;
  void command(const linebridge_msgs::srv::Command_Request& request,
               ddsl::Respond<linebridge_msgs::srv::Command_Response> respond) const;
  void get_parameter(const linebridge_msgs::srv::GetParameter_Request& request,
                     ddsl::Respond<linebridge_msgs::srv::GetParameter_Response> respond) const;
  void set_parameter(const linebridge_msgs::srv::SetParameter_Request& request,
                     ddsl::Respond<linebridge_msgs::srv::SetParameter_Response> respond) const;

  // Whether a request stops its device: it then runs whatever run of the bridge it names
  // (ddsl::ServiceServer's Stops). NMT stop and enter pre-operational (both end operational); a
  // momentary command the profile marks `stopping`. Not the resets: a reset releases any hold and
  // its boot ends in NMT start, so one naming another run is refused unrun, as a start is.
  static bool stops(const linebridge_msgs::srv::Nmt_Request& request);
  bool stops(const linebridge_msgs::srv::Command_Request& request) const;

 private:
  // The named device, or the refusal that names it and lists the line's devices.
  Result<const Device*> find(const std::string& name) const;
  // Refuses with find()'s reason, or gives the device and the request to handle.
  template <class Request, class Reply, class Handle>
  void route(const Request& request, const ddsl::Respond<Reply>& respond, Handle handle) const;
  template <class RequestPS, class ReplyPS>
  Result<void> serve_one(ddsl::Participant& dds, const std::string& service,
                         void (ManagementServices::*handler)(const typename RequestPS::type&,
                                                             ddsl::Respond<typename ReplyPS::type>) const,
                         typename ddsl::ServiceServer<RequestPS, ReplyPS>::Stops stops = {});

  std::string line_;
  // Immutable after construction, so every DDS thread may read them without a lock.
  std::map<std::string, Device, std::less<>> devices_;
  std::string device_list_;          // "saw1, puller1, ..." in configuration order
  std::string command_device_list_;  // the devices that have momentary commands
};

}  // namespace lb::gateways
