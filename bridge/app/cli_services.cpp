#include "app/cli_services.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <map>

#include "canopen/data_type.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::app {

namespace srv = linebridge_msgs::srv;

namespace {

// The request's device field is filled in here: every call names its target device.
template <class Req, class Rep>
Result<typename Rep::type> call(const ServiceTarget& t, const std::string& name, typename Req::type request) {
  request.device(t.device);
  auto client = ddsl::ServiceClient<Req, Rep>::create(t.dds, ddsl::line_service_path(t.line, name));
  if (!client) return client.error();
  return (*client)->call(request, t.timeout);
}

int report(bool ok, const std::string& what, const std::string& message, std::uint32_t abort_code = 0) {
  if (ok) {
    fmt::print("{}\n", what);
    return 0;
  }
  fmt::print(stderr, "refused: {}{}\n", message, abort_code != 0 ? fmt::format(" (abort code {:08X}h)", abort_code) : "");
  return 1;
}

std::string value_text(const srv::ObjectValue& v) {
  const auto type = canopen::parse_data_type(v.data_type());
  if (!type) return "?";
  if (*type == canopen::DataType::visible_string) return "\"" + v.string_value() + "\"";
  if (*type == canopen::DataType::octet_string) return fmt::format("[{:02X}]", fmt::join(v.octets(), " "));
  if (*type == canopen::DataType::real32 || *type == canopen::DataType::real64) return fmt::format("{}", v.real_value());
  if (canopen::is_signed_integer(*type)) return fmt::format("{}", v.integer_value());
  return fmt::format("{} ({:X}h)", v.unsigned_value(), v.unsigned_value());
}

}  // namespace

int call_nmt(const ServiceTarget& t, const std::string& command) {
  static const std::map<std::string, srv::NmtCommand> kCommands{
      {"start", srv::NMT_START},
      {"stop", srv::NMT_STOP},
      {"pre-operational", srv::NMT_ENTER_PRE_OPERATIONAL},
      {"reset-node", srv::NMT_RESET_NODE},
      {"reset-communication", srv::NMT_RESET_COMMUNICATION}};
  srv::Nmt_Request req;
  req.command(kCommands.at(command));
  auto r = call<srv::Nmt_RequestPubSubType, srv::Nmt_ResponsePubSubType>(t, "nmt", req);
  if (!r) return report(false, "", r.error().message);
  return report(r->success(), "NMT " + command + " sent", r->message());
}

int call_sdo_read(const ServiceTarget& t, std::uint16_t index, std::uint8_t sub, const std::string& type) {
  srv::SdoRead_Request req;
  req.index(index);
  req.sub_index(sub);
  req.data_type(type);
  auto r = call<srv::SdoRead_RequestPubSubType, srv::SdoRead_ResponsePubSubType>(t, "sdo_read", req);
  if (!r) return report(false, "", r.error().message);
  return report(r->success(), fmt::format("{:04X}h:{:02X}h = {}", index, sub, value_text(r->value())), r->message(),
                r->abort_code());
}

int call_sdo_write(const ServiceTarget& t, std::uint16_t index, std::uint8_t sub, const std::string& type,
                   const std::string& value) {
  const auto dt = canopen::parse_data_type(type);
  if (!dt) return report(false, "", "unknown data type " + type);
  srv::SdoWrite_Request req;
  req.index(index);
  req.sub_index(sub);
  req.value().data_type(type);
  try {
    if (*dt == canopen::DataType::visible_string) req.value().string_value(value);
    else if (*dt == canopen::DataType::real32 || *dt == canopen::DataType::real64) req.value().real_value(std::stod(value));
    else if (canopen::is_signed_integer(*dt)) req.value().integer_value(std::stoll(value, nullptr, 0));
    else if (*dt == canopen::DataType::octet_string) return report(false, "", "OCTET_STRING writes are not supported by the CLI");
    else req.value().unsigned_value(std::stoull(value, nullptr, 0));
  } catch (const std::exception&) {
    return report(false, "", "'" + value + "' is not a " + type + " value");
  }
  auto r = call<srv::SdoWrite_RequestPubSubType, srv::SdoWrite_ResponsePubSubType>(t, "sdo_write", req);
  if (!r) return report(false, "", r.error().message);
  return report(r->success(), fmt::format("{:04X}h:{:02X}h written", index, sub), r->message(), r->abort_code());
}

int call_get_parameter(const ServiceTarget& t, const std::string& name) {
  srv::GetParameter_Request req;
  req.parameter(name);
  auto r = call<srv::GetParameter_RequestPubSubType, srv::GetParameter_ResponsePubSubType>(t, "get_parameter", req);
  if (!r) return report(false, "", r.error().message);
  return report(r->success(), fmt::format("{} = {} {} (raw {})", name, r->value(), r->unit(), r->raw()), r->message(),
                r->abort_code());
}

int call_set_parameter(const ServiceTarget& t, const std::string& name, double value) {
  srv::SetParameter_Request req;
  req.parameter(name);
  req.value(value);
  auto r = call<srv::SetParameter_RequestPubSubType, srv::SetParameter_ResponsePubSubType>(t, "set_parameter", req);
  if (!r) return report(false, "", r.error().message);
  return report(r->success(), fmt::format("{} set (raw {})", name, r->raw()), r->message(), r->abort_code());
}

int call_command(const ServiceTarget& t, const std::string& name) {
  srv::Command_Request req;
  req.command(name);
  auto r = call<srv::Command_RequestPubSubType, srv::Command_ResponsePubSubType>(t, "command", req);
  if (!r) return report(false, "", r.error().message);
  return report(r->success(), name + " pressed (held 100 ms)", r->message());
}

int call_identity(const ServiceTarget& t) {
  struct Field {
    std::uint16_t index;
    std::uint8_t sub;
    const char* key;
    const char* comment;
  };
  static const Field kFields[] = {
      {0x1000, 0, "device_type", "1000h"},
      {0x1018, 1, "vendor_id", "1018h sub 1"},
      {0x1018, 2, "product_code", "1018h sub 2"},
      {0x1018, 3, "revision", "1018h sub 3: leave it out to accept any revision"},
      {0x1018, 4, "serial_number", "1018h sub 4: this one unit; leave it out to accept any unit of the model"},
  };
  std::string lines;
  for (const auto& f : kFields) {
    srv::SdoRead_Request req;
    req.index(f.index);
    req.sub_index(f.sub);
    req.data_type("UNSIGNED32");
    auto r = call<srv::SdoRead_RequestPubSubType, srv::SdoRead_ResponsePubSubType>(t, "sdo_read", req);
    if (!r) return report(false, "", r.error().message);
    if (!r->success()) {
      if (f.sub >= 2 && r->abort_code() == 0x0609'0011) {  // optional entries (CiA 301)
        lines += fmt::format("      # {}: the device has no {}\n", f.key, f.comment);
        continue;
      }
      return report(false, "", fmt::format("{:04X}h sub {}: {}", f.index, f.sub, r->message()), r->abort_code());
    }
    lines += fmt::format("      {}: 0x{:08X}   # {}\n", f.key, r->value().unsigned_value(), f.comment);
  }
  fmt::print("# {} as it answers now; under its entry in the line file:\n    identity:\n{}", t.device, lines);
  return 0;
}

}  // namespace lb::app
