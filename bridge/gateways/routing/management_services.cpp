#include "gateways/routing/management_services.hpp"

#include "dds/topic_names.hpp"
#include "gateways/adapters/device_services.hpp"
#include "gateways/commands/command_service.hpp"

namespace lb::gateways {

namespace srv = linebridge_msgs::srv;

ManagementServices::ManagementServices(std::string line, std::vector<Device> devices) : line_(std::move(line)) {
  for (auto& d : devices) {
    device_list_ += (device_list_.empty() ? "" : ", ") + d.name;
    if (d.commands != nullptr) command_device_list_ += (command_device_list_.empty() ? "" : ", ") + d.name;
    std::string name = d.name;
    devices_.emplace(std::move(name), std::move(d));
  }
}

template <class RequestPS, class ReplyPS>
Result<void> ManagementServices::serve_one(ddsl::Participant& dds, const std::string& service,
                                           void (ManagementServices::*handler)(const typename RequestPS::type&,
                                                                               ddsl::Respond<typename ReplyPS::type>)
                                               const,
                                           typename ddsl::ServiceServer<RequestPS, ReplyPS>::Stops stops) {
  using Server = ddsl::ServiceServer<RequestPS, ReplyPS>;
  auto served = Server::serve(
      dds, ddsl::line_service_path(line_, service),
      [this, handler](const typename RequestPS::type& request, typename Server::Responder respond) {
        (this->*handler)(request, respond);
      },
      std::move(stops));
  if (!served) return make_error("line-wide service " + service + ": " + served.error().message);
  return {};
}

Result<std::unique_ptr<ManagementServices>> ManagementServices::serve(ddsl::Participant& dds, const std::string& line,
                                                                      std::vector<Device> devices) {
  auto router = std::make_unique<ManagementServices>(line, std::move(devices));
  using M = ManagementServices;
  for (const auto& r :
       {router->serve_one<srv::Nmt_RequestPubSubType, srv::Nmt_ResponsePubSubType>(
            dds, "nmt", &M::nmt, [](const srv::Nmt_Request& r) { return stops(r); }),
        router->serve_one<srv::SdoRead_RequestPubSubType, srv::SdoRead_ResponsePubSubType>(dds, "sdo_read",
                                                                                           &M::sdo_read),
        router->serve_one<srv::SdoWrite_RequestPubSubType, srv::SdoWrite_ResponsePubSubType>(dds, "sdo_write",
                                                                                             &M::sdo_write),
        router->serve_one<srv::Command_RequestPubSubType, srv::Command_ResponsePubSubType>(
            dds, "command", &M::command, [r = router.get()](const srv::Command_Request& c) { return r->stops(c); }),
        router->serve_one<srv::GetParameter_RequestPubSubType, srv::GetParameter_ResponsePubSubType>(dds,
                                                                                                     "get_parameter",
                                                                                                     &M::get_parameter),
        router->serve_one<srv::SetParameter_RequestPubSubType, srv::SetParameter_ResponsePubSubType>(
            dds, "set_parameter", &M::set_parameter)}) {
    if (!r) return r.error();
  }
  return router;
}

Result<const ManagementServices::Device*> ManagementServices::find(const std::string& name) const {
  if (auto it = devices_.find(name); it != devices_.end()) return &it->second;
  const std::string known = device_list_.empty() ? "it has none" : "devices: " + device_list_;
  if (name.empty())
    return make_error("the request names no device (field 'device'; line " + line_ + ": " + known + ")");
  return make_error("no device '" + name + "' on line " + line_ + " (" + known + ")");
}

template <class Request, class Reply, class Handle>
void ManagementServices::route(const Request& request, const ddsl::Respond<Reply>& respond, Handle handle) const {
  auto device = find(request.device());
  if (!device) {
    Reply refused;  // success false
    refused.message(device.error().message);
    return respond(refused);
  }
  handle(**device);
}

void ManagementServices::nmt(const srv::Nmt_Request& request, ddsl::Respond<srv::Nmt_Response> respond) const {
  route(request, respond, [&](const Device& d) { d.services->nmt(request, respond); });
}

void ManagementServices::sdo_read(const srv::SdoRead_Request& request,
                                  ddsl::Respond<srv::SdoRead_Response> respond) const {
  route(request, respond, [&](const Device& d) { d.services->sdo_read(request, respond); });
}

void ManagementServices::sdo_write(const srv::SdoWrite_Request& request,
                                   ddsl::Respond<srv::SdoWrite_Response> respond) const {
  route(request, respond, [&](const Device& d) { d.services->sdo_write(request, respond); });
}

void ManagementServices::command(const srv::Command_Request& request,
                                 ddsl::Respond<srv::Command_Response> respond) const {
  route(request, respond, [&](const Device& d) {
    if (d.commands != nullptr) return d.commands->handle(request, respond);
    srv::Command_Response refused;
    refused.message(d.name + " (" + d.kind + ") has no momentary commands (" +
                    (command_device_list_.empty() ? std::string("no device of line " + line_ + " has any")
                                                  : "devices with commands: " + command_device_list_) +
                    ")");
    respond(refused);
  });
}

bool ManagementServices::stops(const srv::Nmt_Request& request) {
  switch (request.command()) {
    case srv::NMT_STOP:
    case srv::NMT_ENTER_PRE_OPERATIONAL: return true;
    // A reset releases the operator's or the line's hold and its boot ends in NMT start: a repeat
    // of one asked of an earlier run would undo a stop made since. Ordinary, as start is.
    case srv::NMT_RESET_NODE:
    case srv::NMT_RESET_COMMUNICATION:
    default: return false;  // start, or a value the enum lacks (refused by its handler, not run)
  }
}

bool ManagementServices::stops(const srv::Command_Request& request) const {
  const auto it = devices_.find(request.device());
  if (it == devices_.end() || it->second.commands == nullptr) return false;
  for (const auto& c : it->second.commands->commands()) {
    if (c.name == request.command()) return c.stopping;
  }
  return false;
}

void ManagementServices::get_parameter(const srv::GetParameter_Request& request,
                                       ddsl::Respond<srv::GetParameter_Response> respond) const {
  route(request, respond, [&](const Device& d) { d.services->get_parameter(request, respond); });
}

void ManagementServices::set_parameter(const srv::SetParameter_Request& request,
                                       ddsl::Respond<srv::SetParameter_Response> respond) const {
  route(request, respond, [&](const Device& d) { d.services->set_parameter(request, respond); });
}

}  // namespace lb::gateways
