#include "gateways/adapters/saw_gateway.hpp"

#include <spdlog/spdlog.h>

#include <stdexcept>

#include "dds/topic_names.hpp"
#include "gateways/adapters/checked.hpp"
#include "gateways/adapters/device_health.hpp"
#include "gateways/node/pdo_receive.hpp"
#include "gateways/node/set_value_path.hpp"

namespace lb::gateways {

namespace msg = linebridge_msgs::msg;
using profiles::PdoDirection;

namespace {

// The saw's momentary commands (CiA 420-4 6020h), those its profile version has.
std::vector<CommandBit> saw_commands(const SawCodec& codec) {
  return resolve_commands(codec.control_word(), {"manual_cut", "tip_pulse", "stop_immediately", "f1_stop", "f1_start",
                                                 "f2_stop", "f2_start", "f3_stop", "f3_start"});
}

}  // namespace

SawGateway::SawGateway(DeviceContext context)
    : ctx_(context),
      codec_(context.profile, context.device.pdos, !context.is_master()),
      burst_(context.loop, context.cycle, [this](std::int64_t stamp_ns) { publish_status(stamp_ns); }),
      output_(
          ctx_, codec_, [this](std::size_t pdo, const can::CanFrame& f) { on_pdo(pdo, f); },
          {.commands = saw_commands(codec_),
           .silent_until_told = false,
           .refuse_unless_started = false,
           .state_pdo = {}},
          [this] { publish_status(ddsl::now_ns()); }),
      command_service_(context, saw_commands(codec_),
                       [this](const CommandBit& c, const auto& refuse, const MomentaryCommands::Done& done) {
                         output_.press(c, refuse, done);
                       }) {
  const std::string& dev = ctx_.device.name;
  const std::string& line = ctx_.line;
  status_writer_ = checked(ctx_.dds.writer<msg::SawStatusPubSubType>(ddsl::topic_name(line, dev, "status"),
                                                                     ddsl::QosKind::state),
                           dev);
  cut_writer_ = checked(ctx_.dds.writer<msg::SawCutPubSubType>(ddsl::topic_name(line, dev, "cut"),
                                                               ddsl::QosKind::event),
                        dev);
  result_writer_ = checked(ctx_.dds.writer<msg::SetpointResultPubSubType>(ddsl::topic_name(line, dev,
                                                                                           "setpoint_result"),
                                                                          ddsl::QosKind::reply),
                           dev);
  auto sub = ctx_.dds.subscribe<msg::SawSetpointPubSubType>(ddsl::topic_name(line, dev, "setpoint"),
                                                            ddsl::QosKind::command,
                                                            [this](const msg::SawSetpoint& sp,
                                                                   const ddsl::fdds::SampleInfo&) { on_setpoint(sp); });
  if (!sub) throw std::runtime_error(dev + ": " + sub.error().message);

  ctx_.node.attach(*this);
  spdlog::info("{}: saw ({}) node {} on bus {} as {}{}", dev, ctx_.profile.key(), ctx_.device.node_id, ctx_.bus.name,
               profiles::to_string(ctx_.bus.role),
               ctx_.is_master() ? "; what its RPDO1 carries is decided at its start (the start-up policy)" : "");
  publish_status(ddsl::now_ns());  // the device exists (offline) before its first heartbeat
}

void SawGateway::on_nmt_change(canopen::NmtState, bool) noexcept { publish_status(ddsl::now_ns()); }

void SawGateway::on_pdo(std::size_t pdo, const can::CanFrame& frame) {
  if (receive_pdo(ctx_, codec_, burst_, pdo, frame))
    burst_.add(pdo, frame.timestamp_ns, [&] { return cycle_of(codec_, pdo); });
}

void SawGateway::on_setpoint(const msg::SawSetpoint& sp) {
  take_set_value(
      ctx_, output_, set_value_log_, sp.request_id(), [&] { return codec_.validate(sp); },
      [this](const SawCodec::RawSetpoint& r) { codec_.apply(r); },
      [this] {
        if (applied_log_.allow()) {
          spdlog::info("{}: set values: program {}, sync speed {} %, product length {} m (control word {:04X}h){}",
                       ctx_.device.name, status_.control_word().saw_program_on() ? "on" : "off",
                       status_.sync_speed_set_percent(), status_.product_length_set_m(), status_.control_word().raw(),
                       held_back_note(applied_log_));
        }
      },
      [this](std::uint64_t id, bool accepted, const std::string& reason) { reply(id, accepted, reason); });
}

void SawGateway::reply(std::uint64_t request_id, bool accepted, const std::string& reason) {
  msg::SetpointResult r;
  r.request_id(request_id);
  r.accepted(accepted);
  r.reason(reason);
  result_writer_.write(r);
}

void SawGateway::publish_status(std::int64_t stamp_ns) {
  burst_.published();
  const auto stamp = ddsl::to_stamp(stamp_ns);
  status_.stamp().sec(stamp.sec);
  status_.stamp().nanosec(stamp.nanosec);
  fill_health(ctx_.node, status_.health());
  codec_.fill(status_);
  status_.pdo_length_errors(ctx_.node.stats().pdo_length_errors);
  status_writer_.write(status_);

  // The saw loads a new length when its program starts, otherwise only after the next cut.
  const bool program_on = status_.control_word().saw_program_on();
  if (!program_on || !program_was_on_) length_in_force_m_ = status_.product_length_set_m();
  program_was_on_ = program_on;
  const bool cutting = codec_.cutting();
  if (cutting && !was_cutting_) {
    msg::SawCut cut;
    cut.stamp(status_.stamp());
    cut.cut_count(++cut_count_);
    cut.length_in_force_m(length_in_force_m_);
    cut.counter_before_cut_m(counter_before_cut_m_);
    cut_writer_.write(cut);
    length_in_force_m_ = status_.product_length_set_m();
  }
  if (!cutting) counter_before_cut_m_ = status_.actual_saw_counter_m();
  was_cutting_ = cutting;
}

}  // namespace lb::gateways
