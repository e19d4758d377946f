#include "gateways/adapters/feeder_gateway.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>

#include "canopen/sdo_abort.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/adapters/checked.hpp"
#include "gateways/adapters/device_health.hpp"
#include "gateways/node/pdo_receive.hpp"
#include "gateways/node/sdo_admission.hpp"

namespace lb::gateways {

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using profiles::PdoDirection;

namespace {

// Feeder status, error condition and functions have no PDO: they are read by SDO this often
// (and the feeders beyond 32, which FF10h cannot report, are only seen this way).
constexpr auto kPollPeriod = std::chrono::seconds(1);
constexpr std::uint16_t kStatus = 0x6009, kErrorCondition = 0x6007, kControlBoxError = 0x6008, kFunctions = 0x6001;
constexpr std::uint16_t kUnwinding = 0x6010, kLoomStatus = 0x600A, kTrigger = 0x600B, kPicks = 0x600C,
                        kOutputs = 0x600D;
constexpr std::uint16_t kFf10 = 0xFF10;

srv::FeederWrite_Response refused(std::string message) {
  srv::FeederWrite_Response r;
  r.message(std::move(message));
  return r;
}

}  // namespace

FeederGateway::FeederGateway(DeviceContext context)
    : ctx_(context),
      codec_(context.profile, context.device.pdos, !context.is_master()),
      burst_(context.loop, context.cycle, [this](std::int64_t stamp_ns) { publish_status(stamp_ns); }),
      // The loom controller's RPDOs are event-driven (255): they go out when a loom set value
      // changes them, and never before the first one. Only the loom status is a state (sent again
      // to a restarted box); triggers and picks are events.
      output_(
          ctx_, codec_, [this](std::size_t pdo, const can::CanFrame& f) { on_pdo(pdo, f); },
          {.commands = {},
           .silent_until_told = true,
           .refuse_unless_started = true,
           .state_pdo = [this](std::size_t pdo) { return codec_.carries(pdo, kLoomStatus); }},
          [this] { publish_status(ddsl::now_ns()); }) {
  const std::string& dev = ctx_.device.name;

  const std::string& line = ctx_.line;
  using ddsl::QosKind;
  status_writer_ = checked(ctx_.dds.writer<msg::FeederStatusPubSubType>(ddsl::topic_name(line, dev, "status"),
                                                                        QosKind::state),
                           dev);
  unwinding_writer_ = checked(ctx_.dds.writer<msg::FeederUnwindingPubSubType>(ddsl::topic_name(line, dev, "unwinding"),
                                                                              QosKind::event),
                              dev);
  error_writer_ = checked(ctx_.dds.writer<msg::FeederErrorPubSubType>(ddsl::topic_name(line, dev, "feeder_error"),
                                                                      QosKind::event),
                          dev);
  loom_result_writer_ = checked(
      ctx_.dds.writer<msg::SetpointResultPubSubType>(ddsl::topic_name(line, dev, "loom_result"), QosKind::reply), dev);
  auto sub = ctx_.dds.subscribe<msg::LoomSetpointPubSubType>(ddsl::topic_name(line, dev, "loom"), QosKind::command,
                                                             [this](const msg::LoomSetpoint& sp,
                                                                    const ddsl::fdds::SampleInfo&) { on_loom(sp); });
  if (!sub) throw std::runtime_error(dev + ": " + sub.error().message);
  serve_services();

  ctx_.node.attach(*this);
  if (ctx_.is_master() && ctx_.sdo != nullptr) {
    poll_timer_ = ctx_.loop.create_timer([this] { poll(); });
    ctx_.loop.arm_timer(poll_timer_, kPollPeriod, kPollPeriod);
  }
  spdlog::info("{}: feeder control box ({}) node {} on bus {} as {}{}", dev, ctx_.profile.key(), ctx_.device.node_id,
               ctx_.bus.name, profiles::to_string(ctx_.bus.role),
               ctx_.is_master() ? "; loom controller RPDOs stay silent until the first loom set value" : "");
  publish_status(ddsl::now_ns());
}

// ---- CAN -> DDS ----

void FeederGateway::on_pdo(std::size_t pdo, const can::CanFrame& frame) {
  if (!receive_pdo(ctx_, codec_, burst_, pdo, frame)) return;
  if (codec_.pdos()[pdo].def->direction == PdoDirection::tx && codec_.carries(pdo, kUnwinding)) {
    auto u = codec_.last_unwinding();
    ddsl::set_stamp(u, frame.timestamp_ns);
    if (!u.in_range()) ++ctx_.node.stats().range_warnings;  // published all the same: actual values are never dropped
    unwinding_writer_.write(u);
    return;
  }
  // Also a loom controller's RPDO (monitor role). The unwinding TPDO has its own topic above: the
  // status never waits for it.
  burst_.add(pdo, frame.timestamp_ns, [&] {
    auto timing = cycle_of(codec_, pdo);
    for (std::size_t i = 0; i < codec_.pdos().size(); ++i) {
      if (codec_.carries(i, kUnwinding)) timing.each_sync &= ~PdoBurst::bit(i);
    }
    return timing;
  });
}

// A restarted control box gets the loom status again (DeviceOutput: state_pdo).
void FeederGateway::on_nmt_change(canopen::NmtState, bool online) noexcept {
  if (!online) feeder_count_ = -1;
  publish_status(ddsl::now_ns());
}

void FeederGateway::on_emcy(const canopen::Emergency& e) noexcept {
  if (e.error_code == kFf10) {
    // Each FF10h replaces the set of feeders in error (an empty bitmap clears them all).
    const std::uint32_t bitmap = FeederCodec::ff10_bitmap(e.manufacturer);
    const std::uint32_t changed = bitmap ^ bitmap_;
    bitmap_ = bitmap;
    for (unsigned feeder = 1; feeder <= FeederCodec::kBitmapFeeders; ++feeder) {
      if (!FeederCodec::in_bitmap(changed, feeder)) continue;
      entry(feeder).in_error(FeederCodec::in_bitmap(bitmap, feeder));
      publish_error_event(feeder, FeederCodec::in_bitmap(bitmap, feeder), bitmap, e.timestamp_ns);
    }
  }
  publish_status(e.timestamp_ns);
}

void FeederGateway::publish_error_event(unsigned feeder, bool in_error, std::uint32_t bitmap, std::int64_t stamp_ns) {
  msg::FeederError ev;
  ddsl::set_stamp(ev, stamp_ns);
  ev.feeder(static_cast<std::uint8_t>(feeder));
  ev.in_error(in_error);
  ev.bitmap(bitmap);
  if (!ctx_.is_master() || ctx_.sdo == nullptr) {
    ev.remark("bus " + ctx_.bus.name +
              " is in the monitor role: the bridge never transmits, so 6007h could not be read");
    error_writer_.write(ev);
    return;
  }
  // "If feeders are not able to provide detailed failure conditions immediately after the error
  // occurs, the Emergency message will not contain [them]": the detail is in 6007h sub feeder.
  const std::uint32_t bit = FeederCodec::in_bitmap(0xFFFF'FFFFU, feeder) ? 1U << (feeder - 1) : 0U;
  if ((detail_pending_ & bit) != 0) {
    ++detail_reads_coalesced_;
    ev.remark("6007h sub " + std::to_string(feeder) + " not read again: its read is still under way (" +
              std::to_string(detail_reads_coalesced_) + " such events coalesced)");
    error_writer_.write(ev);
    return;
  }
  detail_pending_ |= bit;
  read(kErrorCondition, static_cast<std::uint8_t>(feeder),
       [this, ev, feeder, bit](canopen::SdoClient::ReadResult r) mutable {
         detail_pending_ &= ~bit;
         if (r) {
           const auto raw = canopen::integer_bits(*r);
           ev.detail_read(true);
           ev.condition(codec_.error_condition(raw));
           entry(feeder).error_condition_read(true);
           entry(feeder).error_condition(ev.condition());
           spdlog::info("{}: feeder {} {} (6007h: {})", ctx_.device.name, feeder,
                        ev.in_error() ? "in error" : "error cleared",
                        ev.condition().valid() ? ev.condition().name() : fmt::format("undefined code {:02X}h", raw));
         } else {
           ev.remark("6007h sub " + std::to_string(feeder) + " not read: " + r.error().message);
           spdlog::warn("{}: feeder {} {}; {}", ctx_.device.name, feeder, ev.in_error() ? "in error" : "error cleared",
                        ev.remark());
         }
         error_writer_.write(ev);
         publish_status(ddsl::now_ns());
       });
}

void FeederGateway::poll() {
  // While another master holds the bus (or this bridge stands by) its SDO requests would be held back.
  if (polling_ || !ctx_.node.online() || ctx_.loop.transmission_held()) return;
  polling_ = true;
  auto reads = std::make_shared<std::vector<Read>>();
  reads->push_back({kControlBoxError, 0, [this](std::optional<std::uint64_t> v, std::vector<Read>&) {
                      status_.control_box_error_read(v.has_value());
                      if (v) status_.control_box_error(codec_.control_box_error(*v));
                    }});
  reads->push_back(
      {kStatus, 0, [this](std::optional<std::uint64_t> v, std::vector<Read>& more) {
         status_.feeder_count_read(v.has_value());
         if (!v) return;
         const unsigned count = std::min<unsigned>(static_cast<unsigned>(*v), FeederCodec::kMaxFeeders);
         status_.feeder_count(static_cast<std::uint8_t>(count));
         feeder_count_ = static_cast<int>(count);
         auto& feeders = status_.feeders();
         // Entries beyond the count stay only while FF10h reports them in error.
         feeders.erase(std::remove_if(feeders.begin(), feeders.end(),
                                      [&](const msg::FeederEntry& f) { return f.number() > count && !f.in_error(); }),
                       feeders.end());
         for (unsigned n = 1; n <= count; ++n) {
           const auto sub = static_cast<std::uint8_t>(n);
           (void)entry(n);
           more.push_back({kStatus, sub, [this, n](std::optional<std::uint64_t> s, std::vector<Read>&) {
                             entry(n).status_read(s.has_value());
                             if (s) entry(n).status(codec_.feeder_status(*s));
                           }});
           more.push_back({kErrorCondition, sub, [this, n](std::optional<std::uint64_t> s, std::vector<Read>&) {
                             entry(n).error_condition_read(s.has_value());
                             if (s) entry(n).error_condition(codec_.error_condition(*s));
                           }});
           more.push_back({kFunctions, sub, [this, n](std::optional<std::uint64_t> s, std::vector<Read>&) {
                             entry(n).functions_read(s.has_value());
                             if (s) entry(n).functions(codec_.functions(static_cast<std::uint32_t>(*s)));
                           }});
         }
       }});
  read_chain(reads, 0);
}

void FeederGateway::read_chain(const std::shared_ptr<std::vector<Read>>& reads, std::size_t next) {
  if (next >= reads->size()) {
    polling_ = false;
    publish_status(ddsl::now_ns());
    return;
  }
  const Read& r = (*reads)[next];
  read(r.index, r.sub, [this, reads, next](canopen::SdoClient::ReadResult result) {
    // The count read adds the per-feeder reads: appended after it ran, never while it runs.
    std::vector<Read> more;
    (*reads)[next].apply(result ? std::optional(canopen::integer_bits(*result)) : std::nullopt, more);
    for (auto& m : more) reads->push_back(std::move(m));
    // A local general error means the client is going away (or the bus refused the frame): stop
    // here rather than queue more requests.
    if (!result && (result.error().abort_code == canopen::sdo_abort::general_error || !ctx_.node.online())) {
      polling_ = false;
      return;
    }
    read_chain(reads, next + 1);
  });
}

msg::FeederEntry& FeederGateway::entry(unsigned feeder) {
  auto& feeders = status_.feeders();
  auto it = std::lower_bound(feeders.begin(), feeders.end(), feeder,
                             [](const msg::FeederEntry& e, unsigned n) { return e.number() < n; });
  if (it == feeders.end() || it->number() != feeder) {
    msg::FeederEntry e;
    e.number(static_cast<std::uint8_t>(feeder));
    e.in_error(FeederCodec::in_bitmap(bitmap_, feeder));
    it = feeders.insert(it, e);
  }
  return *it;
}

void FeederGateway::publish_status(std::int64_t stamp_ns) {
  burst_.published();
  ddsl::set_stamp(status_, stamp_ns);
  fill_health(ctx_.node, status_.health());
  status_.error_bitmap(bitmap_);
  codec_.fill_loom(status_.loom(), outputs_in_use());
  codec_.fill_other_values(status_.other_values());
  status_.pdo_length_errors(ctx_.node.stats().pdo_length_errors);
  status_writer_.write(status_);
}

// ---- DDS -> CAN ----

std::string FeederGateway::refusal() const {
  if (!ctx_.is_master() || ctx_.sdo == nullptr) {
    return "bus " + ctx_.bus.name + " is in the monitor role: the bridge never transmits there";
  }
  return {};
}

std::optional<unsigned> FeederGateway::feeder_count() const {
  const int n = feeder_count_.load();
  return n < 0 ? std::nullopt : std::optional<unsigned>(static_cast<unsigned>(n));
}

void FeederGateway::read(std::uint16_t index, std::uint8_t sub, canopen::SdoClient::ReadDone done,
                         std::optional<canopen::SdoClient::Limit> limit) {
  // By the profile's type, so a device that answers without size indication is read right.
  const auto* obj = ctx_.profile.object(index, sub);
  ctx_.sdo->read(ctx_.device.node_id, index, sub, obj != nullptr ? obj->type : canopen::DataType::unsigned32,
                 std::move(done), limit);
}

void FeederGateway::when_sdo_possible(const WriteReply& reply, std::function<void()> send, bool stop) {
  gateways::when_sdo_possible(
      ctx_, std::move(send), [reply](const std::string& why) { reply(refused(why)); }, {}, stop);
}

void FeederGateway::write(const FeederCodec::Write& w, const WriteReply& reply, std::function<void()> then, bool stop) {
  when_sdo_possible(
      reply, [this, w, reply, then = std::move(then), stop] { write_now(w, reply, then, stop); }, stop);
}

void FeederGateway::write_now(const FeederCodec::Write& w, WriteReply reply, std::function<void()> then, bool stop) {
  const auto* obj = w.object;
  auto limit = kServiceSdoLimit;
  limit.stops = stop;
  ctx_.sdo->write(
      ctx_.device.node_id, obj->index, obj->sub, obj->type, canopen::ObjectValue{w.raw},
      [this, obj, raw = w.raw, reply = std::move(reply), then = std::move(then),
       stop](const canopen::SdoClient::DownloadResult& r) {
        if (r && then) return then();
        srv::FeederWrite_Response resp;
        resp.success(r.has_value());
        resp.raw(raw);
        // A stop is accepted once it is on the bus, as a stop by PDO is (canopen-master.md, the
        // stop path): a heard device that answers none of its attempts (stalled, busy resetting)
        // did get the frames; only its own abort or a frame never sent refuses it.
        if (!r && stop && r.error().abort_code == canopen::sdo_abort::timed_out) {
          resp.success(true);
          resp.abort_code(r.error().abort_code);
          resp.message(obj->name + ": on the bus, not confirmed: " + r.error().message);
          spdlog::warn("{}: {} = {:X}h sent, not confirmed by the device: {}", ctx_.device.name, obj->name, raw,
                       r.error().message);
        } else if (!r) {
          resp.abort_code(r.error().abort_code);
          resp.message(obj->name + ": " + r.error().message);
          spdlog::warn("{}: {} = {:X}h refused by the device: {}", ctx_.device.name, obj->name, raw, r.error().message);
        } else {
          spdlog::info("{}: {} = {:X}h written", ctx_.device.name, obj->name, raw);
        }
        reply(resp);
      },
      limit);
}

template <class RequestPS>
void FeederGateway::serve(const std::string& name,
                          std::function<void(const typename RequestPS::type&, WriteReply)> handler,
                          std::function<bool(const typename RequestPS::type&)> stops) {
  // Every service: refused in the monitor role, validated against the profile on the DDS thread,
  // and only then an SDO request.
  using Service = ddsl::ServiceServer<RequestPS, srv::FeederWrite_ResponsePubSubType>;
  auto served = Service::serve(
      ctx_.dds, ctx_.line + "/" + ctx_.device.name + "/" + name,
      [this, handler = std::move(handler)](const typename RequestPS::type& req, typename Service::Responder respond) {
        const WriteReply reply = [respond](srv::FeederWrite_Response r) { respond(r); };
        if (auto why = refusal(); !why.empty()) return reply(refused(why));
        handler(req, reply);
      },
      std::move(stops));
  if (!served) throw std::runtime_error(ctx_.device.name + ": " + served.error().message);
}

void FeederGateway::serve_services() {
  const auto write_or_refuse = [this](Result<FeederCodec::Write> w, const WriteReply& reply, bool stop = false) {
    if (!w) {
      if (auto more = refusal_log_.allow())
        spdlog::warn("{}: refused: {}{}", ctx_.device.name, w.error().message, *more);
      return reply(refused(w.error().message));
    }
    write(*w, reply, {}, stop);
  };
  // 600Eh: the two commands that take a feeder out of operation. They go whenever the box is heard.
  const auto stops = [](const srv::FeederCommand_Request& req) {
    return req.command() == "stop_mode" || req.command() == "non_operation_mode";
  };

  serve<srv::FeederCommand_RequestPubSubType>(
      "feeder_command",
      [this, write_or_refuse, stops](const srv::FeederCommand_Request& req, const WriteReply& reply) {
        write_or_refuse(codec_.command(req.feeder(), req.command(), req.manufacturer_code(), feeder_count()), reply,
                        stops(req));
      },
      stops);
  serve<srv::FeederTest_RequestPubSubType>("feeder_test", [this, write_or_refuse](const srv::FeederTest_Request& req,
                                                                                  const WriteReply& reply) {
    write_or_refuse(codec_.test(req.feeder(), req.test(), req.parameter(), feeder_count()), reply);
  });
  serve<srv::WeftInsertionType_RequestPubSubType>("weft_insertion_type",
                                                  [this, write_or_refuse](const srv::WeftInsertionType_Request& req,
                                                                          const WriteReply& reply) {
                                                    write_or_refuse(codec_.weft_insertion_type(req.type()), reply);
                                                  });
  serve<srv::FeederAssignment_RequestPubSubType>(
      "feeder_assignment", [this, write_or_refuse](const srv::FeederAssignment_Request& req, const WriteReply& reply) {
        if (!req.set_number() && !req.set_color()) return reply(refused("nothing to assign: set_number or set_color"));
        std::optional<FeederCodec::Write> number, color;
        if (req.set_number()) {
          auto w = codec_.number_assignment(req.feeder(), req.system_number(), feeder_count());
          if (!w) return write_or_refuse(std::move(w), reply);
          number = *w;
        }
        if (req.set_color()) {
          auto w = codec_.color_assignment(req.feeder(), req.color(), feeder_count());
          if (!w) return write_or_refuse(std::move(w), reply);
          color = *w;
        }
        // Both checked before either is written; the colour follows a successful number write.
        if (number && color) return write(*number, reply, [this, c = *color, reply] { write_now(c, reply); });
        write(number ? *number : *color, reply);
      });
  serve<srv::FeederFunctions_RequestPubSubType>("feeder_functions", [this](const srv::FeederFunctions_Request& req,
                                                                           const WriteReply& reply) {
    auto obj = codec_.functions_object(req.feeder(), feeder_count());
    if (!obj) return reply(refused(obj.error().message));
    std::vector<FeederCodec::FunctionSetting> settings;
    for (const auto& s : req.settings()) settings.push_back({s.function(), s.state()});
    // Read-modify-write: only functions the feeder reports as available may change.
    when_sdo_possible(reply, [this, o = *obj, settings = std::move(settings), reply] {
      read(
          o->index, o->sub,
          [this, o, settings, reply](canopen::SdoClient::ReadResult r) {
            if (!r) {
              auto resp = refused(o->name + " not read: " + r.error().message);
              resp.abort_code(r.error().abort_code);
              return reply(resp);
            }
            auto merged = codec_.merge_functions(canopen::integer_bits(*r), settings);
            if (!merged) return reply(refused(merged.error().message));
            auto w = FeederCodec::checked(*o, *merged);
            if (!w) return reply(refused(w.error().message));
            write_now(*w, reply);
          },
          kServiceSdoLimit);
    });
  });
  serve<srv::TriggerSource_RequestPubSubType>("trigger_source", [this](const srv::TriggerSource_Request& req,
                                                                       const WriteReply& reply) {
    std::vector<std::string> selected(req.selected().begin(), req.selected().end());
    const auto& supported = codec_.trigger_sources_supported();
    when_sdo_possible(reply, [this, &supported, selected = std::move(selected), reply] {
      read(
          supported.index, supported.sub,
          [this, selected, reply](canopen::SdoClient::ReadResult r) {
            if (!r) {
              auto resp = refused("trigger_sources_supported not read: " + r.error().message);
              resp.abort_code(r.error().abort_code);
              return reply(resp);
            }
            auto w = codec_.trigger_sources(selected, canopen::integer_bits(*r));
            if (!w) return reply(refused(w.error().message));
            write_now(*w, reply);
          },
          kServiceSdoLimit);
    });
  });
}

void FeederGateway::on_loom(const msg::LoomSetpoint& sp) {
  if (auto why = refusal(); !why.empty()) return loom_reply(sp.request_id(), false, why);
  auto raw = codec_.validate(sp);
  if (!raw) {
    if (auto more = refusal_log_.allow()) {
      spdlog::warn("{}: loom set value {} refused: {}{}", ctx_.device.name, sp.request_id(), raw.error().message,
                   *more);
    }
    return loom_reply(sp.request_id(), false, raw.error().message);
  }
  const bool posted = ctx_.loop.try_post([this, r = *raw, id = sp.request_id()] {
    if (!r.outputs.empty() && !outputs_in_use()) {
      return loom_reply(id, false,
                        ctx_.device.name + ": RPDO3 (600Dh digital outputs) is not in use: the box does not have "
                                           "it, or it is disabled (COB-ID bit 31); loom set value not sent");
    }
    // Each part given is an event on its own PDO, sent even when unchanged (a trigger repeats).
    std::vector<std::size_t> touched;
    for (const auto& t : output_.rpdos()) {
      if ((r.loom_status && codec_.carries(t.pdo, kLoomStatus)) || (r.trigger && codec_.carries(t.pdo, kTrigger)) ||
          (r.picks && codec_.carries(t.pdo, kPicks)) || (!r.outputs.empty() && codec_.carries(t.pdo, kOutputs))) {
        touched.push_back(t.pdo);
      }
    }
    const bool first = !loom_played_;
    output_.take([this, &r] { codec_.apply(r); },
                 [this, id, first](bool accepted, const std::string& reason) {
                   if (accepted && first) {
                     loom_played_ = true;
                     spdlog::info("{}: the bridge now plays the loom controller (RPDOs from here on)",
                                  ctx_.device.name);
                   }
                   if (!accepted) {
                     if (auto more = refusal_log_.allow())
                       spdlog::warn("{}: loom set value {} refused: {}{}", ctx_.device.name, id, reason, *more);
                   }
                   loom_reply(id, accepted, reason);
                 },
                 touched);
  });
  if (!posted) loom_reply(sp.request_id(), false, ctx_.loop_busy("loom set value"));
}

bool FeederGateway::outputs_in_use() {
  if (!ctx_.is_master()) {
    // A monitor decodes the loom controller's RPDO3 when the line has it enabled.
    for (std::size_t i = 0; i < codec_.pdos().size(); ++i) {
      const auto& def = *codec_.pdos()[i].def;
      if (def.direction == PdoDirection::rx && def.enabled && codec_.carries(i, kOutputs)) return true;
    }
    return false;
  }
  for (const auto& t : output_.rpdos()) {
    if (t.valid_on_device && codec_.carries(t.pdo, kOutputs)) return true;
  }
  return false;
}

void FeederGateway::loom_reply(std::uint64_t request_id, bool accepted, const std::string& reason) {
  msg::SetpointResult r;
  r.request_id(request_id);
  r.accepted(accepted);
  r.reason(reason);
  loom_result_writer_.write(r);
}

}  // namespace lb::gateways
