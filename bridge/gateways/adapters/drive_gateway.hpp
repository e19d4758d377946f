#pragma once
// A CiA 420 drive (puller, corrugator) on DDS, as the saw is: TPDOs decoded into
// rt/<line>/<device>/status, set values from rt/<line>/<device>/setpoint validated and sent in
// RPDO1 at every SYNC (master role) or the line controller's RPDO1 decoded (monitor role), and the
// momentary control bits for the line-wide command service.
// Binding: the type's generated word binding (msgs/word_bindings.hpp); instantiated once per
// drive-shaped binding, by make_gateway.cpp.

#include <spdlog/spdlog.h>

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "base/shared_log_rate.hpp"
#include "canopen/pdo_transmitter.hpp"
#include "dds/topic_names.hpp"
#include "gateways/adapters/device_health.hpp"
#include "gateways/adapters/gateway.hpp"
#include "gateways/codecs/drive_codec.hpp"
#include "gateways/commands/command_service.hpp"
#include "gateways/node/device_output.hpp"
#include "gateways/node/pdo_burst.hpp"
#include "gateways/node/pdo_receive.hpp"
#include "gateways/node/set_value_path.hpp"
#include "msgs/commonPubSubTypes.h"

namespace lb::gateways {

template <class Binding>
class DriveGateway : public Gateway {
 public:
  using Codec = DriveCodec<Binding>;
  using Status = typename Codec::Status;
  using Setpoint = typename Codec::Setpoint;

  // Throws std::runtime_error at start-up when the profile lacks what the device needs.
  explicit DriveGateway(DeviceContext context);

  const CommandService* commands() const override { return &command_service_; }

  // NodeDriver: what the node hears (both roles). The SYNC and the RPDOs are the output's.
  void on_nmt_change(canopen::NmtState, bool) noexcept override { publish_status(ddsl::now_ns()); }
  void on_emcy(const canopen::Emergency& e) noexcept override { publish_status(e.timestamp_ns); }
  void on_errors() noexcept override { publish_status(ddsl::now_ns()); }

 private:
  void on_pdo(std::size_t pdo, const can::CanFrame& frame);
  void on_setpoint(const Setpoint& sp);
  void publish_status(std::int64_t stamp_ns);
  void reply(std::uint64_t request_id, bool accepted, const std::string& reason);

  DeviceContext ctx_;
  SharedLogRate set_value_log_;  // refusals, from DDS threads and the loop
  LogRate applied_log_;          // set values taken, on the loop
  Codec codec_;                  // loop thread, except validate() (const, any thread)
  PdoBurst burst_;
  DeviceOutput<Codec> output_;      // the RPDO image and what of it goes out
  CommandService command_service_;  // presses through output_
  ddsl::Writer<typename Binding::StatusTopic> status_writer_;
  ddsl::Writer<linebridge_msgs::msg::SetpointResultPubSubType> result_writer_;
  Status status_;  // loop thread
  bool echo_mismatch_logged_ = false;
};

template <class Binding>
DriveGateway<Binding>::DriveGateway(DeviceContext context)
    : ctx_(context),
      codec_(context.profile, context.device.pdos, {}, !context.is_master()),
      burst_(context.loop, context.cycle, [this](std::int64_t stamp_ns) { publish_status(stamp_ns); }),
      output_(
          ctx_, codec_, [this](std::size_t pdo, const can::CanFrame& f) { on_pdo(pdo, f); },
          {.commands = resolve_commands(codec_.bitset("control_word"), momentary_commands<Binding>()),
           .silent_until_told = false,
           .refuse_unless_started = false,
           .state_pdo = {}},
          [this] { publish_status(ddsl::now_ns()); }),
      command_service_(context, resolve_commands(codec_.bitset("control_word"), momentary_commands<Binding>()),
                       [this](const CommandBit& c, const auto& refuse, MomentaryCommands::Done done) {
                         output_.press(c, refuse, std::move(done));
                       }) {
  namespace msg = linebridge_msgs::msg;
  const std::string& dev = ctx_.device.name;
  const auto fail = [&dev](const Error& e) { throw std::runtime_error(dev + ": " + e.message); };
  auto status = ctx_.dds.writer<typename Binding::StatusTopic>(ddsl::topic_name(ctx_.line, dev, "status"),
                                                               ddsl::QosKind::state);
  if (!status) fail(status.error());
  status_writer_ = *status;
  auto result = ctx_.dds.writer<msg::SetpointResultPubSubType>(ddsl::topic_name(ctx_.line, dev, "setpoint_result"),
                                                               ddsl::QosKind::reply);
  if (!result) fail(result.error());
  result_writer_ = *result;
  auto sub = ctx_.dds.subscribe<typename Binding::SetpointTopic>(
      ddsl::topic_name(ctx_.line, dev, "setpoint"), ddsl::QosKind::command,
      [this](const Setpoint& sp, const ddsl::fdds::SampleInfo&) { on_setpoint(sp); });
  if (!sub) fail(sub.error());

  ctx_.node.attach(*this);
  spdlog::info("{}: {} ({}) node {} on bus {} as {}{}", dev, ctx_.profile.device, ctx_.profile.key(),
               ctx_.device.node_id, ctx_.bus.name, profiles::to_string(ctx_.bus.role),
               ctx_.is_master() ? "; what its RPDO1 carries is decided at its start (the start-up policy)" : "");
  publish_status(ddsl::now_ns());  // the device exists (offline) before its first heartbeat
}

template <class Binding>
void DriveGateway<Binding>::on_pdo(std::size_t pdo, const can::CanFrame& frame) {
  if (!receive_pdo(ctx_, codec_, burst_, pdo, frame)) return;
  if (codec_.set_echo_mismatch() != echo_mismatch_logged_) {
    echo_mismatch_logged_ = codec_.set_echo_mismatch();
    if (echo_mismatch_logged_) {
      spdlog::warn("{}: set echo {} % differs from the set value {} % beyond the settling time", ctx_.device.name,
                   codec_.speed_set_echo_percent(), codec_.speed_set_percent());
    } else {
      spdlog::info("{}: set echo agrees with the set value again", ctx_.device.name);
    }
  }
  burst_.add(pdo, frame.timestamp_ns, [&] { return cycle_of(codec_, pdo); });
}

template <class Binding>
void DriveGateway<Binding>::on_setpoint(const Setpoint& sp) {
  take_set_value(
      ctx_, output_, set_value_log_, sp.request_id(), [&] { return codec_.validate(sp); },
      [this](const auto& r) { codec_.apply(r); },
      [this] {
        if (applied_log_.allow()) {
          spdlog::info("{}: set values: extruder {}, speed {} % (control word {:04X}h){}", ctx_.device.name,
                       codec_.extruder_running() ? "running" : "stopped", codec_.speed_set_percent(),
                       codec_.control_word(), held_back_note(applied_log_));
        }
      },
      [this](std::uint64_t id, bool accepted, const std::string& reason) { reply(id, accepted, reason); });
}

template <class Binding>
void DriveGateway<Binding>::reply(std::uint64_t request_id, bool accepted, const std::string& reason) {
  linebridge_msgs::msg::SetpointResult r;
  r.request_id(request_id);
  r.accepted(accepted);
  r.reason(reason);
  result_writer_.write(r);
}

template <class Binding>
void DriveGateway<Binding>::publish_status(std::int64_t stamp_ns) {
  burst_.published();
  const auto stamp = ddsl::to_stamp(stamp_ns);
  status_.stamp().sec(stamp.sec);
  status_.stamp().nanosec(stamp.nanosec);
  fill_health(ctx_.node, status_.health());
  codec_.fill(status_);
  status_.pdo_length_errors(ctx_.node.stats().pdo_length_errors);
  status_writer_.write(status_);
}

}  // namespace lb::gateways
