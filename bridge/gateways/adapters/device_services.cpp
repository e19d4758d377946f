#include "gateways/adapters/device_services.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "canopen/error_field.hpp"
#include "canopen/sdo_abort.hpp"
#include "dds/topic_names.hpp"
#include "gateways/node/pdo_specs.hpp"
#include "gateways/node/sdo_admission.hpp"

namespace lb::gateways {

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using canopen::DataType;

namespace {

std::optional<canopen::NmtCommand> to_command(srv::NmtCommand c) {
  switch (c) {
    case srv::NMT_START: return canopen::NmtCommand::start;
    case srv::NMT_STOP: return canopen::NmtCommand::stop;
    case srv::NMT_ENTER_PRE_OPERATIONAL: return canopen::NmtCommand::enter_pre_operational;
    case srv::NMT_RESET_NODE: return canopen::NmtCommand::reset_node;
    case srv::NMT_RESET_COMMUNICATION: return canopen::NmtCommand::reset_communication;
  }
  return std::nullopt;
}

// The field of srv::ObjectValue that matches the type carries the value.
Result<canopen::ObjectValue> from_msg(DataType type, const srv::ObjectValue& v) {
  if (type == DataType::visible_string) return canopen::ObjectValue{v.string_value()};
  if (type == DataType::octet_string)
    return canopen::ObjectValue{std::vector<std::uint8_t>(v.octets().begin(), v.octets().end())};
  if (type == DataType::real32 || type == DataType::real64) return canopen::ObjectValue{v.real_value()};
  if (canopen::is_signed_integer(type)) return canopen::ObjectValue{v.integer_value()};
  return canopen::ObjectValue{v.unsigned_value()};
}

// How every service refuses: its reply with the reason, success false.
template <class Response>
auto refuser(ddsl::Respond<Response> respond) {
  return [respond = std::move(respond)](const std::string& why) {
    Response r;
    r.message(why);
    respond(r);
  };
}

srv::ObjectValue to_msg(DataType type, const canopen::ObjectValue& value) {
  srv::ObjectValue v;
  v.data_type(std::string(canopen::to_string(type)));
  std::visit(
      [&v](const auto& x) {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, std::int64_t>)
          v.integer_value(x);
        else if constexpr (std::is_same_v<T, std::uint64_t>)
          v.unsigned_value(x);
        else if constexpr (std::is_same_v<T, double>)
          v.real_value(x);
        else if constexpr (std::is_same_v<T, std::string>)
          v.string_value(x);
        else
          v.octets(x);
      },
      value);
  return v;
}

// The completion of a service's SDO write: success, or the abort code and message.
template <class Reply, class Respond>
canopen::SdoClient::DownloadDone sdo_written(Respond respond, std::int64_t raw) {
  return [respond, raw](const canopen::SdoClient::DownloadResult& result) {
    Reply reply;
    reply.success(result.has_value());
    if constexpr (requires { reply.raw(raw); }) {
      reply.raw(raw);
    } else {
      (void)raw;  // a reply without the value written
    }
    if (!result) {
      reply.abort_code(result.error().abort_code);
      reply.message(result.error().message);
    }
    respond(reply);
  };
}

}  // namespace

DeviceServices::DeviceServices(DeviceContext context) : ctx_(context) {
  const std::string& dev = ctx_.device.name;
  const auto fail = [&dev](const Error& e) { throw std::runtime_error(dev + ": " + e.message); };

  auto ew = ctx_.dds.writer<msg::EmergencyPubSubType>(ddsl::topic_name(ctx_.line, dev, "emergency"),
                                                      ddsl::QosKind::event);
  if (!ew) fail(ew.error());
  emergency_writer_ = *ew;
  auto iw = ctx_.dds.writer<msg::DeviceInfoPubSubType>(ddsl::topic_name(ctx_.line, dev, "info"), ddsl::QosKind::state);
  if (!iw) fail(iw.error());
  info_writer_ = *iw;

  ctx_.node.attach(*this);
  configuration_bits_ = ctx_.profile.bitset("configuration_word");
  set_configuration_word(std::nullopt, configuration_bits_ == nullptr
                                           ? "profile " + ctx_.profile.key() + " has no configuration word"
                                           : "not read yet (read after the device's boot passed)");
  if (ctx_.is_master() && ctx_.sdo != nullptr) {
    const auto& d = ctx_.device;
    canopen::BootSequence::Settings boot;
    boot.identity = {static_cast<std::uint16_t>(ctx_.profile.device_type & 0xFFFF),
                     d.identity.device_type,
                     d.identity.vendor_id,
                     d.identity.product_code,
                     d.identity.revision,
                     d.identity.serial_number};
    boot.pdos = pdo_specs(ctx_.profile, d);
    boot.adopt_device_pdos = d.pdo_config == profiles::PdoConfigMode::adopt;
    boot.pdo_change_when_running = ctx_.startup.pdo_change_when_running;
    for (const auto& w : d.configure) boot.writes.push_back({w.index, w.sub, w.type, w.value, w.verify});
    if (d.heartbeat_producer) boot.heartbeat_producer_ms = static_cast<std::uint16_t>(d.heartbeat_producer->count());
    canopen::NodeStateMachine::Settings control;
    control.on_state_unknown = d.on_state_unknown == profiles::StateUnknownAction::reset_node
                                   ? canopen::RecoveryAction::reset_node
                                   : canopen::RecoveryAction::reboot;
    control.retry = d.boot_retry;
    control.reset_bound = std::max(2 * d.heartbeat_timeout, std::chrono::milliseconds(2000));
    machine_ = std::make_unique<canopen::NodeStateMachine>(ctx_.loop, ctx_.node, *ctx_.sdo, std::move(boot), control);
    error_check_timer_ = ctx_.loop.create_timer([this] {
      error_check_armed_ = false;
      read_register_after_emcy();
    });
  }
}

void DeviceServices::on_nmt_change(canopen::NmtState, bool online) noexcept {
  if (!online && ctx_.is_master() && ctx_.sdo != nullptr) {
    ctx_.sdo->cancel_waiting(ctx_.device.node_id, ctx_.device.name + " went offline (no heartbeat)");
  }
}

void DeviceServices::on_emcy(const canopen::Emergency& e) noexcept {
  const auto& errors = ctx_.node.errors();
  msg::Emergency m;
  ddsl::set_stamp(m, e.timestamp_ns);
  m.error_code(e.error_code);
  m.error_register(e.error_register);
  m.manufacturer(e.manufacturer);
  m.family(std::string(canopen::emcy_family(e.error_code)));
  m.active_errors(errors.codes());
  m.active_errors_known(errors.known());
  m.active_errors_note(errors.note());
  emergency_writer_.write(m);
  // The register being read may predate this EMCY: reconciling with it would undo what the EMCY said.
  if (reading_errors_) reread_errors_ = true;
  if (error_check_in_flight_) error_check_again_ = true;
  // A device that runs says itself whether the error is active: the list has something to check.
  if (errors_to_check()) check_errors_after_emcy();
}

bool DeviceServices::errors_to_check() const {
  const auto& errors = ctx_.node.errors();
  // Not while another master holds the bus (a standby, one that stepped back): it transmits nothing.
  return machine_ && report_.started && !reading_errors_ && !ctx_.loop.transmission_held() && ctx_.node.online() &&
         ctx_.node.state() == canopen::NmtState::operational && (!errors.codes().empty() || !errors.known());
}

void DeviceServices::check_errors_after_emcy() {
  if (error_check_in_flight_) {
    error_check_again_ = true;
    return;
  }
  if (error_check_armed_) return;  // the read is due already, and reads the register as it is then
  constexpr auto kAtMostEvery = std::chrono::seconds(1);
  const auto wait = std::max<std::chrono::steady_clock::duration>(std::chrono::steady_clock::duration::zero(),
                                                                  error_check_at_ + kAtMostEvery -
                                                                      std::chrono::steady_clock::now());
  error_check_armed_ = true;
  ctx_.loop.arm_timer(error_check_timer_, wait);
}

void DeviceServices::read_register_after_emcy() {
  if (!errors_to_check()) return;  // gone, booting, or nothing left to check since
  error_check_in_flight_ = true;
  error_check_again_ = false;
  error_check_at_ = std::chrono::steady_clock::now();
  ctx_.sdo->read(ctx_.device.node_id, 0x1001, 0, DataType::unsigned8, [this](canopen::SdoClient::ReadResult r) {
    error_check_in_flight_ = false;
    if (error_check_again_) {  // an EMCY came meanwhile: this answer may predate it, read after it
      if (errors_to_check()) check_errors_after_emcy();
      return;
    }
    if (!r) {
      spdlog::info("{}: error register 1001h not read after an EMCY: {}", ctx_.device.name, r.error().message);
      return;
    }
    const auto reg = static_cast<std::uint8_t>(canopen::integer_bits(*r));
    std::vector<std::uint16_t> cleared;
    ctx_.node.update_errors([&](canopen::ActiveErrors& a) { cleared = a.checked_after_emcy(reg); });
    if (!cleared.empty()) {
      spdlog::warn("{}: EMCY {:04X}h no longer listed as active: the device's own error register 1001h reads 00h (an "
                   "error gone by then, or an EMCY it never sent: CAN frames are not authenticated)",
                   ctx_.device.name, fmt::join(cleared, " "));
    }
  });
}

void DeviceServices::read_errors() {
  if (reading_errors_) {  // the reading under way may predate what made this one necessary
    reread_errors_ = true;
    return;
  }
  reading_errors_ = true;
  reread_errors_ = false;
  canopen::read_error_field(*ctx_.sdo, ctx_.device.node_id, {}, [this](canopen::ErrorFieldReading reading) {
    reading_errors_ = false;
    if (reread_errors_) return read_errors();
    ctx_.node.update_errors([&reading](canopen::ActiveErrors& a) { canopen::apply(a, reading); });
    if (!report_.started) return;  // a newer boot failed meanwhile: its info is out, without a history
    error_history_ = std::move(reading.history);
    const auto& errors = ctx_.node.errors();
    std::vector<std::string> history;
    for (const auto entry : error_history_.entries) history.push_back(fmt::format("{:04X}", entry & 0xFFFF));
    spdlog::info("{}: active errors from the device: [{:04X}]{}{}; error register 1001h {:02X}h; error history 1003h{}",
                 ctx_.device.name, fmt::join(errors.codes(), " "),
                 errors.known() ? "" : ", uncertain: ", errors.known() ? "" : errors.note(), errors.error_register(),
                 error_history_.read
                     ? fmt::format(" ({} recorded, newest first): [{}]", error_history_.count, fmt::join(history, " "))
                     : ": " + error_history_.remark);
    read_configuration_word_and_publish();
  });
}

// After every boot attempt; one that passed first reads what the device says about itself (its
// error register and error history, then 6010h), so `info` and the status tell the truth from then on.
// A device adopted at a takeover comes here too once its identity was read (report.adopted), and
// goes the same way: uploads only, as everything on this path.
void DeviceServices::booted(const canopen::BootReport& report) {
  report_ = report;
  ++boots_reported_;
  error_history_ = {};
  error_history_.remark = report.started ? "not read yet" : "not read: the boot did not pass";
  if (!report.started || ctx_.sdo == nullptr) return publish_info();
  read_errors();
}

void DeviceServices::read_configuration_word_and_publish() {
  const auto seq = boots_reported_;
  if (configuration_bits_ == nullptr) return publish_info();
  ctx_.sdo->read(ctx_.device.node_id, configuration_bits_->index, configuration_bits_->sub,
                 ctx_.profile.object(configuration_bits_->index, configuration_bits_->sub)->type,
                 [this, seq](canopen::SdoClient::ReadResult r) {
                   if (seq != boots_reported_) return;  // a newer boot began meanwhile
                   if (r)
                     set_configuration_word(canopen::integer_bits(*r), "");
                   else
                     set_configuration_word(std::nullopt, "6010h not read: " + r.error().message);
                   publish_info();
                 });
}

void DeviceServices::set_configuration_word(std::optional<std::uint64_t> raw, const std::string& remark) {
  auto& w = configuration_word_;
  w.read(raw.has_value());
  w.remark(remark);
  w.flags().clear();
  if (!raw) {
    w.raw(0);
    return;
  }
  w.raw(static_cast<std::uint32_t>(*raw));
  for (const auto& f : configuration_bits_->bits) {
    if (f.width != 1) continue;
    msg::NamedFlag flag;
    flag.name(f.name);
    flag.bit(static_cast<std::uint8_t>(f.bit));
    flag.on(f.extract(*raw) != 0);
    w.flags().push_back(std::move(flag));
  }
}

void DeviceServices::start() {
  if (machine_) machine_->start();
}

void DeviceServices::take_over(std::optional<canopen::NmtCommand> last_command) {
  if (machine_) machine_->take_over(last_command);
}

void DeviceServices::sdo_read(const srv::SdoRead_Request& req, const ddsl::Respond<srv::SdoRead_Response>& respond) {
  const auto refuse = refuser(respond);
  const auto type = canopen::parse_data_type(req.data_type());
  if (!type) {
    return refuse("unknown data type '" + req.data_type() +
                  "' (INTEGER8..64, UNSIGNED8..64, REAL32, REAL64, VISIBLE_STRING, OCTET_STRING)");
  }
  if (auto why = refusal(); !why.empty()) return refuse(why);
  when_sdo_possible(
      ctx_,
      [this, respond, t = *type, index = req.index(), sub = req.sub_index()] {
        ctx_.sdo->read(
            ctx_.device.node_id, index, sub, t,
            [respond, t](canopen::SdoClient::ReadResult result) {
              srv::SdoRead_Response reply;
              if (result) {
                reply.success(true);
                reply.value(to_msg(t, *result));
              } else {
                reply.abort_code(result.error().abort_code);
                reply.message(result.error().message);
              }
              respond(reply);
            },
            kServiceSdoLimit);
      },
      refuse, [this] { return answered_boot(); });
}

void DeviceServices::sdo_write(const srv::SdoWrite_Request& req, const ddsl::Respond<srv::SdoWrite_Response>& respond) {
  const auto refuse = refuser(respond);
  const auto type = canopen::parse_data_type(req.value().data_type());
  if (!type) return refuse("unknown data type '" + req.value().data_type() + "'");
  if (auto why = refusal(); !why.empty()) return refuse(why);
  auto value = from_msg(*type, req.value());
  if (!value) return refuse(value.error().message);
  when_sdo_possible(
      ctx_,
      [this, respond, t = *type, v = *value, index = req.index(), sub = req.sub_index()] {
        ctx_.sdo->write(ctx_.device.node_id, index, sub, t, v, sdo_written<srv::SdoWrite_Response>(respond, 0),
                        kServiceSdoLimit);
      },
      refuse, [this] { return answered_boot(); });
}

void DeviceServices::get_parameter(const srv::GetParameter_Request& req,
                                   const ddsl::Respond<srv::GetParameter_Response>& respond) {
  const auto refuse = refuser(respond);
  const auto* obj = ctx_.profile.object(req.parameter());
  if (obj == nullptr) return refuse("profile " + ctx_.profile.key() + " has no object '" + req.parameter() + "'");
  if (!obj->readable()) return refuse(req.parameter() + " is write-only");
  if (auto why = refusal(); !why.empty()) return refuse(why);
  when_sdo_possible(
      ctx_,
      [this, respond, obj] {
        ctx_.sdo->read(
            ctx_.device.node_id, obj->index, obj->sub, obj->type,
            [this, respond, obj](canopen::SdoClient::ReadResult result) {
              srv::GetParameter_Response reply;
              if (!result) {
                reply.abort_code(result.error().abort_code);
                reply.message(result.error().message);
                return respond(reply);
              }
              const auto raw = canopen::integer_bits(*result);
              reply.success(true);
              reply.value(obj->to_engineering(raw));
              reply.unit(obj->eng_unit);
              reply.raw(canopen::is_signed_integer(obj->type) ? canopen::sign_extend(raw, canopen::bit_size(obj->type))
                                                              : static_cast<std::int64_t>(raw));
              respond(reply);
              // Read on demand: info tells the new value.
              if (configuration_bits_ != nullptr && configuration_bits_->applies_to(obj->index, obj->sub)) {
                set_configuration_word(raw, "");
                if (boots_reported_ > 0) publish_info();
              }
            },
            kServiceSdoLimit);
      },
      refuse, [this] { return answered_boot(); });
}

void DeviceServices::set_parameter(const srv::SetParameter_Request& req,
                                   const ddsl::Respond<srv::SetParameter_Response>& respond) {
  const auto refuse = refuser(respond);
  const auto* obj = ctx_.profile.object(req.parameter());
  if (obj == nullptr) return refuse("profile " + ctx_.profile.key() + " has no object '" + req.parameter() + "'");
  if (!obj->writable())
    return refuse(req.parameter() + " is " + std::string(profiles::to_string(obj->access)) + ", not writable");
  if (auto why = refusal(); !why.empty()) return refuse(why);
  auto raw = obj->to_raw(req.value());  // range of the profile, rounded to the raw unit
  if (!raw) return refuse(raw.error().message);
  const auto bits = canopen::bit_size(obj->type);
  const bool is_signed = canopen::is_signed_integer(obj->type);
  const std::int64_t shown = is_signed ? canopen::sign_extend(*raw, bits) : static_cast<std::int64_t>(*raw);
  const canopen::ObjectValue value = is_signed ? canopen::ObjectValue{shown} : canopen::ObjectValue{*raw};
  when_sdo_possible(
      ctx_,
      [this, respond, obj, value, shown] {
        ctx_.sdo->write(ctx_.device.node_id, obj->index, obj->sub, obj->type, value,
                        sdo_written<srv::SetParameter_Response>(respond, shown), kServiceSdoLimit);
      },
      refuse, [this] { return answered_boot(); });
}

std::string DeviceServices::refusal() const {
  if (!ctx_.is_master() || ctx_.sdo == nullptr) {
    return "bus " + ctx_.bus.name + " is in the monitor role: the bridge never transmits there";
  }
  return {};
}

void DeviceServices::nmt(const srv::Nmt_Request& request, const ddsl::Respond<srv::Nmt_Response>& respond) {
  const auto reply = [respond](bool ok, std::string message) {
    srv::Nmt_Response r;
    r.success(ok);
    r.message(std::move(message));
    respond(r);
  };
  const auto command = to_command(request.command());
  if (!command) return reply(false, "unknown NMT command " + std::to_string(static_cast<int>(request.command())));
  if (auto why = refusal(); !why.empty()) return reply(false, why);
  const bool posted = ctx_.loop.try_post([this, c = *command, reply] {
    // The node state machine keeps what an operator asks (canopen/node_state_machine.hpp).
    if (auto r = machine_->operator_command(c); !r) return reply(false, ctx_.device.name + " " + r.error().message);
    spdlog::info("{}: NMT command {:02X}h sent on request", ctx_.device.name, static_cast<int>(c));
    for (const auto& l : nmt_listeners_) l(c);
    // NMT is unconfirmed (CiA 301): success says it was sent, and only the device's heartbeat
    // tells that it was heard. A device that has none (offline) may be gone, or only silent:
    // sending may still help (a reset), so it is sent and answered sent, with what is not known.
    if (!ctx_.node.online()) {
      const bool stops = c == canopen::NmtCommand::stop || c == canopen::NmtCommand::enter_pre_operational;
      if (stops && ctx_.node.heard()) {
        return reply(true, ctx_.device.name +
                               " sends no heartbeat just now, but it is heard (its other frames): a stop goes out");
      }
      const bool resets = c == canopen::NmtCommand::reset_node || c == canopen::NmtCommand::reset_communication;
      return reply(true, ctx_.device.name + " was not heard before (no heartbeat within its timeout): " +
                             (resets ? "its boot-up" : "its heartbeat") + " will tell that it took effect");
    }
    reply(true, "");
  });
  if (!posted) reply(false, ctx_.loop_busy("NMT command"));
}

void DeviceServices::publish_info() {
  const auto& report = report_;
  const auto& id = report.identity;
  msg::DeviceInfo m;
  ddsl::set_stamp(m, id.read_at_ns);
  m.node_id(ctx_.device.node_id);
  m.device_type(id.device_type);
  m.profile_number(static_cast<std::uint16_t>(id.device_type & 0xFFFF));
  m.vendor_id(id.vendor_id);
  m.product_code(id.product_code);
  m.revision_number(id.revision_number);
  m.serial_number(id.serial_number);
  m.device_name(id.device_name);
  m.hardware_version(id.hardware_version);
  m.software_version(id.software_version);
  // 1000h bits 0..15 tell only the profile family (420 or 414); the part comes from the config.
  m.profile_matches(id.device_type != 0 && (id.device_type & 0xFFFF) == (ctx_.profile.device_type & 0xFFFF));
  std::string remarks = id.remarks;
  for (const auto& w : report.warnings) remarks += w + "; ";
  m.remarks(remarks);
  m.started(report.started);
  if (report.error) m.boot_error(to_msg(*report.error));
  m.pdo_config(std::string(profiles::to_string(ctx_.device.pdo_config)));
  for (const auto& p : report.pdos) m.pdos().push_back(to_msg(p));
  m.heartbeat_producer_ms(report.heartbeat_producer_ms ? *report.heartbeat_producer_ms : -1);
  m.configuration_word(configuration_word_);
  m.error_history_read(error_history_.read);
  m.error_history_count(error_history_.count);
  m.error_history(error_history_.entries);
  m.error_history_remark(error_history_.remark);
  if (report.started) {
    spdlog::info(
        "{}: identity{}: vendor {:08X}h product {:08X}h rev {:08X}h serial {:08X}h, \"{}\" hw \"{}\" sw \"{}\"{}",
        ctx_.device.name, report.adopted ? " (adopted at a takeover)" : "", id.vendor_id, id.product_code,
        id.revision_number, id.serial_number, id.device_name, id.hardware_version, id.software_version,
        configuration_word_.read() ? fmt::format(", configuration word {:08X}h", configuration_word_.raw()) : "");
  } else if (report.error) {
    spdlog::warn("{}: not started: {}", ctx_.device.name, report.error->message);
  }
  info_writer_.write(m);
}

msg::BootError to_msg(const canopen::BootError& e) {
  msg::BootError m;
  if (e.code != 0) m.code(std::string(1, e.code));
  m.step(e.step);
  m.index(e.index);
  m.sub_index(e.sub);
  m.expected(e.expected);
  m.actual(e.actual);
  m.abort_code(e.abort_code);
  m.message(e.message);
  return m;
}

msg::PdoInfo to_msg(const canopen::PdoInUse& p) {
  msg::PdoInfo m;
  m.name(p.name);
  m.cob_id(p.parameters.cob_id);
  m.transmission_type(p.parameters.transmission_type);
  m.inhibit_time_100us(p.parameters.inhibit_time);
  m.event_timer_ms(p.parameters.event_timer);
  for (const auto& e : p.parameters.mapping) m.mapping().push_back(e.to_u32());
  m.adopted(p.adopted);
  return m;
}

}  // namespace lb::gateways
