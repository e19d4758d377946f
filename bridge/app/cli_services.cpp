#include "app/cli_services.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <map>
#include <optional>

#include "app/cli_exit.hpp"
#include "canopen/data_type.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/routing/bridge_runs.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/feederPubSubTypes.h"

namespace lb::app {

namespace srv = linebridge_msgs::srv;

namespace {

// A reply, or why there is none. A refusal by a bridge that restarted after the request was first
// sent is told apart from every other answer (restarted()): the request may have run before.
template <class Rep>
struct Answered {
  std::optional<Error> error;  // no answer at all
  typename Rep::type reply{};
  bool bridge_restarted = false;

  explicit operator bool() const { return !error; }
  const typename Rep::type* operator->() const { return &reply; }
};

template <class Req, class Rep>
Answered<Rep> ask(const std::string& path, const ServiceTarget& t, const typename Req::type& request) {
  auto client = ddsl::ServiceClient<Req, Rep>::create(t.dds, path, gateways::bridge_runs(t.line));
  if (!client) return {client.error()};
  auto answer = (*client)->ask(request, t.timeout);
  if (!answer) return {answer.error()};
  return {std::nullopt, answer->reply, answer->bridge_restarted()};
}

// The request's device field is filled in here: every call names its target device.
template <class Req, class Rep>
Answered<Rep> call(const ServiceTarget& t, const std::string& name, typename Req::type request) {
  request.device(t.device);
  return ask<Req, Rep>(ddsl::line_service_path(t.line, name), t, request);
}

// A device's own service (a feeder box's typed services): <line>/<device>/<service>.
template <class Req, class Rep>
Answered<Rep> call_device(const ServiceTarget& t, const std::string& name, const typename Req::type& request) {
  return ask<Req, Rep>(t.line + "/" + t.device + "/" + name, t, request);
}

int report(bool ok, const std::string& what, const std::string& message, std::uint32_t abort_code = 0) {
  if (ok) {
    fmt::print("{}\n", what);
    return kExitOk;
  }
  fmt::print(stderr, "refused: {}{}\n", message,
             abort_code != 0 ? fmt::format(" (abort code {:08X}h)", abort_code) : "");
  return kExitRefused;
}

// Nothing was sent: the arguments are wrong.
int usage(const std::string& message) {
  fmt::print(stderr, "{}\n", message);
  return kExitUsage;
}

// No answer at all: no bridge, a timeout, a request that could not be sent; or the answer of a
// bridge that restarted since the request was first sent (it did not run it; the first run may have).
template <class Rep>
int not_answered(const Answered<Rep>& a) {
  if (a.bridge_restarted) {
    fmt::print(stderr, "bridge restarted: {}\n", a.reply.message());
    return kExitBridgeRestarted;
  }
  fmt::print(stderr, "no answer: {}\n", a.error->message);
  return kExitNoAnswer;
}

std::string value_text(const srv::ObjectValue& v) {
  const auto type = canopen::parse_data_type(v.data_type());
  if (!type) return "?";
  if (*type == canopen::DataType::visible_string) return "\"" + v.string_value() + "\"";
  if (*type == canopen::DataType::octet_string) return fmt::format("[{:02X}]", fmt::join(v.octets(), " "));
  if (*type == canopen::DataType::real32 || *type == canopen::DataType::real64)
    return fmt::format("{}", v.real_value());
  if (canopen::is_signed_integer(*type)) return fmt::format("{}", v.integer_value());
  return fmt::format("{} ({:X}h)", v.unsigned_value(), v.unsigned_value());
}

}  // namespace

int call_nmt(const ServiceTarget& t, const std::string& command) {
  static const std::map<std::string, srv::NmtCommand> kCommands{{"start", srv::NMT_START},
                                                                {"stop", srv::NMT_STOP},
                                                                {"pre-operational", srv::NMT_ENTER_PRE_OPERATIONAL},
                                                                {"reset-node", srv::NMT_RESET_NODE},
                                                                {"reset-communication", srv::NMT_RESET_COMMUNICATION}};
  srv::Nmt_Request req;
  req.command(kCommands.at(command));
  auto r = call<srv::Nmt_RequestPubSubType, srv::Nmt_ResponsePubSubType>(t, "nmt", req);
  if (!r || r.bridge_restarted) return not_answered(r);
  // Sent is success: NMT is unconfirmed, and the bridge's message says what is not known yet.
  return report(r->success(), "NMT " + command + " sent" + (r->message().empty() ? "" : "; " + r->message()),
                r->message());
}

int call_sdo_read(const ServiceTarget& t, std::uint16_t index, std::uint8_t sub, const std::string& type) {
  srv::SdoRead_Request req;
  req.index(index);
  req.sub_index(sub);
  req.data_type(type);
  auto r = call<srv::SdoRead_RequestPubSubType, srv::SdoRead_ResponsePubSubType>(t, "sdo_read", req);
  if (!r || r.bridge_restarted) return not_answered(r);
  return report(r->success(), fmt::format("{:04X}h:{:02X}h = {}", index, sub, value_text(r->value())), r->message(),
                r->abort_code());
}

int call_sdo_write(const ServiceTarget& t, std::uint16_t index, std::uint8_t sub, const std::string& type,
                   const std::string& value) {
  const auto dt = canopen::parse_data_type(type);
  if (!dt) return usage("unknown data type " + type);
  srv::SdoWrite_Request req;
  req.index(index);
  req.sub_index(sub);
  req.value().data_type(type);
  try {
    if (*dt == canopen::DataType::visible_string)
      req.value().string_value(value);
    else if (*dt == canopen::DataType::real32 || *dt == canopen::DataType::real64)
      req.value().real_value(std::stod(value));
    else if (canopen::is_signed_integer(*dt))
      req.value().integer_value(std::stoll(value, nullptr, 0));
    else if (*dt == canopen::DataType::octet_string)
      return usage("OCTET_STRING writes are not supported by the CLI");
    else
      req.value().unsigned_value(std::stoull(value, nullptr, 0));
  } catch (const std::exception&) {
    return usage("'" + value + "' is not a " + type + " value");
  }
  auto r = call<srv::SdoWrite_RequestPubSubType, srv::SdoWrite_ResponsePubSubType>(t, "sdo_write", req);
  if (!r || r.bridge_restarted) return not_answered(r);
  return report(r->success(), fmt::format("{:04X}h:{:02X}h written", index, sub), r->message(), r->abort_code());
}

int call_get_parameter(const ServiceTarget& t, const std::string& name) {
  srv::GetParameter_Request req;
  req.parameter(name);
  auto r = call<srv::GetParameter_RequestPubSubType, srv::GetParameter_ResponsePubSubType>(t, "get_parameter", req);
  if (!r || r.bridge_restarted) return not_answered(r);
  return report(r->success(), fmt::format("{} = {} {} (raw {})", name, r->value(), r->unit(), r->raw()), r->message(),
                r->abort_code());
}

int call_set_parameter(const ServiceTarget& t, const std::string& name, double value) {
  srv::SetParameter_Request req;
  req.parameter(name);
  req.value(value);
  auto r = call<srv::SetParameter_RequestPubSubType, srv::SetParameter_ResponsePubSubType>(t, "set_parameter", req);
  if (!r || r.bridge_restarted) return not_answered(r);
  return report(r->success(), fmt::format("{} set (raw {})", name, r->raw()), r->message(), r->abort_code());
}

int call_command(const ServiceTarget& t, const std::string& name) {
  srv::Command_Request req;
  req.command(name);
  auto r = call<srv::Command_RequestPubSubType, srv::Command_ResponsePubSubType>(t, "command", req);
  if (!r || r.bridge_restarted) return not_answered(r);
  return report(r->success(),
                fmt::format("{}: on the bus in {} RPDO(s) over {:.1f} ms, then released{}{}", name, r->frames(),
                            r->held_ms(), r->message().empty() ? "" : "; ", r->message()),
                r->message());
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
    if (!r || r.bridge_restarted) return not_answered(r);
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

namespace {

template <class Req>
int feeder_call(const ServiceTarget& t, const std::string& service, const typename Req::type& request,
                const std::string& what) {
  auto r = call_device<Req, srv::FeederWrite_ResponsePubSubType>(t, service, request);
  if (!r || r.bridge_restarted) return not_answered(r);
  return report(r->success(), fmt::format("{} written ({:X}h)", what, r->raw()), r->message(), r->abort_code());
}

}  // namespace

int call_feeder_command(const ServiceTarget& t, unsigned feeder, const std::string& command, unsigned code) {
  srv::FeederCommand_Request req;
  req.feeder(static_cast<std::uint8_t>(feeder));
  req.command(command);
  req.manufacturer_code(static_cast<std::uint8_t>(code));
  return feeder_call<srv::FeederCommand_RequestPubSubType>(t, "feeder_command", req,
                                                           fmt::format("feeder {} {}", feeder, command));
}

int call_feeder_test(const ServiceTarget& t, unsigned feeder, const std::string& test, unsigned parameter) {
  srv::FeederTest_Request req;
  req.feeder(static_cast<std::uint8_t>(feeder));
  req.test(test);
  req.parameter(static_cast<std::uint8_t>(parameter));
  return feeder_call<srv::FeederTest_RequestPubSubType>(t, "feeder_test", req,
                                                        fmt::format("feeder {} test {} {}", feeder, test, parameter));
}

int call_feeder_functions(const ServiceTarget& t, unsigned feeder, const std::vector<std::string>& settings) {
  srv::FeederFunctions_Request req;
  req.feeder(static_cast<std::uint8_t>(feeder));
  for (const auto& s : settings) {
    const auto eq = s.find('=');
    if (eq == std::string::npos) {
      fmt::print(stderr, "'{}': give FUNCTION=STATE, e.g. yarn_break_sensor=active\n", s);
      return kExitUsage;
    }
    srv::FeederFunctionSetting setting;
    setting.function(s.substr(0, eq));
    setting.state(s.substr(eq + 1));
    req.settings().push_back(setting);
  }
  return feeder_call<srv::FeederFunctions_RequestPubSubType>(t, "feeder_functions", req,
                                                             fmt::format("feeder {} functions {}", feeder,
                                                                         fmt::join(settings, " ")));
}

int call_feeder_assignment(const ServiceTarget& t, unsigned feeder, std::optional<unsigned> number,
                           std::optional<unsigned> color) {
  srv::FeederAssignment_Request req;
  req.feeder(static_cast<std::uint8_t>(feeder));
  req.set_number(number.has_value());
  req.system_number(static_cast<std::uint8_t>(number.value_or(0)));
  req.set_color(color.has_value());
  req.color(static_cast<std::uint8_t>(color.value_or(0)));
  return feeder_call<srv::FeederAssignment_RequestPubSubType>(t, "feeder_assignment", req,
                                                              fmt::format("feeder {} assignment", feeder));
}

int call_weft_insertion_type(const ServiceTarget& t, const std::string& type) {
  srv::WeftInsertionType_Request req;
  req.type(type);
  return feeder_call<srv::WeftInsertionType_RequestPubSubType>(t, "weft_insertion_type", req,
                                                               "weft insertion type " + type);
}

int call_trigger_source(const ServiceTarget& t, const std::vector<std::string>& selected) {
  srv::TriggerSource_Request req;
  for (const auto& s : selected) req.selected().push_back(s);
  return feeder_call<srv::TriggerSource_RequestPubSubType>(t, "trigger_source", req,
                                                           fmt::format("trigger sources [{}]",
                                                                       fmt::join(selected, " ")));
}

}  // namespace lb::app
