#pragma once
// The operator of the safety table's line: every request it makes over DDS (a set value, a
// momentary or feeder command, an NMT command), logged with the moment it was written (realtime,
// the clock the bus stamps frames with) and its answer, for the judge (safety_judge.hpp). One
// panel per set-value type; the line-wide services are shared.

#include <chrono>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/routing/bridge_runs.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/corrugatorPubSubTypes.h"
#include "msgs/feederPubSubTypes.h"
#include "msgs/pullerPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "msgs/winderPubSubTypes.h"
#include "support/collector.hpp"
#include "support/safety_device.hpp"
#include "support/safety_request.hpp"
#include "support/spy_waits.hpp"

namespace lb::test::safety {

inline constexpr std::chrono::seconds kAnswerDeadline{15};

using CommandClient = ddsl::ServiceClient<linebridge_msgs::srv::Command_RequestPubSubType,
                                          linebridge_msgs::srv::Command_ResponsePubSubType>;
using NmtClient =
    ddsl::ServiceClient<linebridge_msgs::srv::Nmt_RequestPubSubType, linebridge_msgs::srv::Nmt_ResponsePubSubType>;
using FeederCommandClient = ddsl::ServiceClient<linebridge_msgs::srv::FeederCommand_RequestPubSubType,
                                                linebridge_msgs::srv::FeederWrite_ResponsePubSubType>;

// What a panel needs of the line: its participant and names.
struct PanelContext {
  ddsl::Participant& dds;
  std::string line;
  const SafetyDevice& device;
};

class OperatorPanel {
 public:
  virtual ~OperatorPanel() = default;
  // A set value with the enabling level(s) on, or all off; written, and answered or not.
  virtual OperatorRequest set_enabling(bool on) = 0;
  // The stopping command; pressed, and answered or not.
  virtual OperatorRequest press_stop() = 0;
  // Bridge readers the set-value writer has matched so far (a restarted bridge's reader adds one).
  virtual int matches() const = 0;
  // The services this panel uses answer a harmless request (refused: nothing reaches the bus), so
  // a request written next reaches the bridge at once; false after the deadline.
  virtual bool warm() = 0;
};

namespace detail {

template <class Client>
std::unique_ptr<Client> make_client(ddsl::Participant& dds, const std::string& path, const std::string& line) {
  auto c = Client::create(dds, path, gateways::bridge_runs(line));
  if (!c) throw std::runtime_error(path + ": " + c.error().message);
  return std::move(*c);
}

// A set-value writer and its answers (SetpointResult by request_id).
template <class SetpointPS>
class SetValueWriter {
 public:
  SetValueWriter(ddsl::Participant& dds, const std::string& topic, const std::string& result_topic) {
    auto w = dds.writer<SetpointPS>(topic, ddsl::QosKind::command);
    if (!w) throw std::runtime_error(topic + ": " + w.error().message);
    writer_ = *w;
    if (auto r = results_.subscribe(dds, result_topic, ddsl::QosKind::reply); !r)
      throw std::runtime_error(result_topic + ": " + r.error().message);
  }
  int matches() const {
    eprosima::fastdds::dds::PublicationMatchedStatus status;
    writer_.entity()->get_publication_matched_status(status);
    return status.total_count;
  }
  // Writes the sample, fills in when and what the answer was.
  void write(typename SetpointPS::type sample, OperatorRequest& r) {
    sample.request_id(++last_id_);
    r.written_ns = bus_now_ns();
    writer_.write(sample);
    await(last_id_, r);
  }
  // Writes a sample the bridge must refuse (nothing reaches the bus) until one is answered.
  bool warm(typename SetpointPS::type sample) {
    const auto deadline = std::chrono::steady_clock::now() + kAnswerDeadline;
    while (std::chrono::steady_clock::now() < deadline) {
      sample.request_id(++last_id_);
      writer_.write(sample);
      if (results_.wait(std::chrono::seconds(1), [&](const auto& v) { return answer_of(v, last_id_) != nullptr; }))
        return true;
    }
    return false;
  }

 private:
  static const linebridge_msgs::msg::SetpointResult* answer_of(
      const std::vector<linebridge_msgs::msg::SetpointResult>& v, std::uint64_t id) {
    for (const auto& x : v) {
      if (x.request_id() == id) return &x;
    }
    return nullptr;
  }
  void await(std::uint64_t id, OperatorRequest& r) {
    if (!results_.wait(kAnswerDeadline, [&](const auto& v) { return answer_of(v, id) != nullptr; })) return;
    r.answered_ns = bus_now_ns();
    const auto v = results_.samples();
    const auto* a = answer_of(v, id);
    r.accepted = a->accepted();
    r.reason = a->reason();
  }

  ddsl::Writer<SetpointPS> writer_;
  Collector<linebridge_msgs::msg::SetpointResultPubSubType> results_;
  // Distinct over the bridge's restarts (the bridge keeps no request ids across runs, but a test
  // that reads answers by id must not meet an earlier one's).
  std::uint64_t last_id_ = static_cast<std::uint64_t>(bus_now_ns() / 1000);
};

// The line-wide momentary command (CiA 420 types): the profile's stopping command.
class LineCommand {
 public:
  explicit LineCommand(const PanelContext& ctx)
      : device_(ctx.device.name),
        client_(make_client<CommandClient>(ctx.dds, ddsl::line_service_path(ctx.line, "command"), ctx.line)) {}
  OperatorRequest press(const std::string& name) {
    OperatorRequest r;
    linebridge_msgs::srv::Command_Request req;
    req.device(device_);
    req.command(name);
    r.written_ns = bus_now_ns();
    auto a = client_->call(req, kAnswerDeadline);
    if (!a) {
      r.reason = "(no answer: " + a.error().message + ")";
      return r;
    }
    r.answered_ns = bus_now_ns();
    r.accepted = a->success();
    r.reason = a->message();
    return r;
  }
  bool warm() {
    // An unknown command is refused before anything reaches the bus.
    return press("no_such_command").answered_ns != 0;
  }

 private:
  std::string device_;
  std::unique_ptr<CommandClient> client_;
};

class SawPanel final : public OperatorPanel {
 public:
  explicit SawPanel(const PanelContext& ctx)
      : ctx_(ctx),
        set_values_(ctx.dds, ddsl::topic_name(ctx.line, ctx.device.name, "setpoint"),
                    ddsl::topic_name(ctx.line, ctx.device.name, "setpoint_result")),
        command_(ctx) {}
  OperatorRequest set_enabling(bool on) override {
    OperatorRequest r;
    r.kind = on ? OperatorRequest::Kind::enabling_on : OperatorRequest::Kind::enabling_off;
    r.what = on ? "set value: saw_program_on and wall_thickening on, 50 %, 1.2 m"
                : "set value: saw_program_on and wall_thickening off, 50 %, 1.2 m";
    if (!on) r.proofs = ctx_.device.off_frames;
    set_values_.write(sample(on, 50), r);
    return r;
  }
  OperatorRequest press_stop() override {
    auto r = command_.press(ctx_.device.stopping_command);
    r.kind = OperatorRequest::Kind::stopping;
    r.what = "command " + ctx_.device.stopping_command;
    r.proofs = {ctx_.device.stop_frame};
    return r;
  }
  int matches() const override { return set_values_.matches(); }
  bool warm() override {
    // 1000 % is over 6005h's printed 100.00 %: refused before the bus.
    return set_values_.warm(sample(false, 1000)) && command_.warm();
  }

 private:
  static linebridge_msgs::msg::SawSetpoint sample(bool on, double speed) {
    linebridge_msgs::msg::SawSetpoint sp;
    sp.saw_program_on(on);
    sp.wall_thickening(on);
    sp.sync_speed_percent(speed);
    sp.product_length_m(1.2);
    return sp;
  }
  PanelContext ctx_;
  SetValueWriter<linebridge_msgs::msg::SawSetpointPubSubType> set_values_;
  LineCommand command_;
};

// Puller, corrugator and winder set values: extruder_running and speed_set_percent.
template <class SetpointPS>
class DrivePanel final : public OperatorPanel {
 public:
  explicit DrivePanel(const PanelContext& ctx)
      : ctx_(ctx),
        set_values_(ctx.dds, ddsl::topic_name(ctx.line, ctx.device.name, "setpoint"),
                    ddsl::topic_name(ctx.line, ctx.device.name, "setpoint_result")),
        command_(ctx) {}
  OperatorRequest set_enabling(bool on) override {
    OperatorRequest r;
    r.kind = on ? OperatorRequest::Kind::enabling_on : OperatorRequest::Kind::enabling_off;
    r.what = on ? "set value: extruder_running on, 50 %" : "set value: extruder_running off, 50 %";
    if (!on) r.proofs = ctx_.device.off_frames;
    set_values_.write(sample(on, 50), r);
    return r;
  }
  OperatorRequest press_stop() override {
    auto r = command_.press(ctx_.device.stopping_command);
    r.kind = OperatorRequest::Kind::stopping;
    r.what = "command " + ctx_.device.stopping_command;
    r.proofs = {ctx_.device.stop_frame};
    return r;
  }
  int matches() const override { return set_values_.matches(); }
  bool warm() override {
    // 1000 % is over 6002h's printed -100..100 %: refused before the bus.
    return set_values_.warm(sample(false, 1000)) && command_.warm();
  }

 private:
  static typename SetpointPS::type sample(bool on, double speed) {
    typename SetpointPS::type sp;
    sp.extruder_running(on);
    sp.speed_set_percent(speed);
    return sp;
  }
  PanelContext ctx_;
  SetValueWriter<SetpointPS> set_values_;
  LineCommand command_;
};

// The feeder box with the bridge as loom controller: LoomSetpoint on `loom`, feeder_command.
class LoomPanel final : public OperatorPanel {
 public:
  explicit LoomPanel(const PanelContext& ctx)
      : ctx_(ctx),
        set_values_(ctx.dds, ddsl::topic_name(ctx.line, ctx.device.name, "loom"),
                    ddsl::topic_name(ctx.line, ctx.device.name, "loom_result")) {
    auto c = FeederCommandClient::create(ctx.dds, ctx.line + "/" + ctx.device.name + "/feeder_command");
    if (!c) throw std::runtime_error("feeder_command: " + c.error().message);
    commands_ = std::move(*c);
  }
  OperatorRequest set_enabling(bool on) override {
    OperatorRequest r;
    r.kind = on ? OperatorRequest::Kind::enabling_on : OperatorRequest::Kind::enabling_off;
    r.what = on ? "loom set value: start_advice, 600 1/min, 1.9 m, output group 1 = 01h"
                : "loom set value: stop, 600 1/min, 1.9 m, output group 1 = 00h";
    if (!on) r.proofs = ctx_.device.off_frames;
    linebridge_msgs::msg::LoomSetpoint sp;
    sp.loom_status(on ? "start_advice" : "stop");
    sp.maximum_speed_per_min(600);
    sp.loom_width_m(1.9);
    sp.digital_outputs({static_cast<std::uint8_t>(on ? 0x01 : 0x00)});
    set_values_.write(sp, r);
    return r;
  }
  OperatorRequest press_stop() override {
    auto r = feeder_command(ctx_.device.stopping_command);
    r.kind = OperatorRequest::Kind::stopping;
    r.what = "feeder_command 1 " + ctx_.device.stopping_command;
    r.proofs = {ctx_.device.stop_frame};
    return r;
  }
  int matches() const override { return set_values_.matches(); }
  bool warm() override {
    // DDh is a reserved pick code: refused before the bus; an unknown feeder command too.
    linebridge_msgs::msg::LoomSetpoint bad;
    bad.pick_insertion({0x00, 0x07, 0xDD, 0xA3, 0x55});
    return set_values_.warm(bad) && feeder_command("no_such_command").answered_ns != 0;
  }

 private:
  OperatorRequest feeder_command(const std::string& name) {
    OperatorRequest r;
    linebridge_msgs::srv::FeederCommand_Request req;
    req.feeder(1);
    req.command(name);
    r.written_ns = bus_now_ns();
    auto a = commands_->call(req, kAnswerDeadline);
    if (!a) {
      r.reason = "(no answer: " + a.error().message + ")";
      return r;
    }
    r.answered_ns = bus_now_ns();
    r.accepted = a->success();
    r.reason = a->message();
    return r;
  }
  PanelContext ctx_;
  SetValueWriter<linebridge_msgs::msg::LoomSetpointPubSubType> set_values_;
  std::unique_ptr<FeederCommandClient> commands_;
};

}  // namespace detail

// An NMT command for the device (the line-wide nmt service), written and answered or not; NMT
// stop is a stop, shown by its frame 000#02XX.
inline OperatorRequest nmt_request(NmtClient& client, const SafetyDevice& device,
                                   linebridge_msgs::srv::NmtCommand command) {
  OperatorRequest r;
  const auto node = static_cast<std::uint8_t>(device.node);
  switch (command) {
    case linebridge_msgs::srv::NMT_STOP:
      r.kind = OperatorRequest::Kind::nmt_stop;
      r.what = "NMT stop";
      r.proofs = {{fmt::format("000#02{:02X} (NMT stop)", node), [node](const lb::can::CanFrame& f) {
                     return f.id == 0 && f.len == 2 && f.data[0] == 0x02 && f.data[1] == node;
                   }}};
      break;
    case linebridge_msgs::srv::NMT_START:
      r.kind = OperatorRequest::Kind::nmt_start;
      r.what = "NMT start";
      break;
    case linebridge_msgs::srv::NMT_RESET_NODE: r.what = "NMT reset node"; break;
    default: r.what = "NMT command"; break;
  }
  linebridge_msgs::srv::Nmt_Request req;
  req.device(device.name);
  req.command(command);
  r.written_ns = bus_now_ns();
  auto a = client.call(req, kAnswerDeadline);
  if (a) {
    r.answered_ns = bus_now_ns();
    r.accepted = a->success();
    r.reason = a->message();
  } else {
    r.reason = "(no answer: " + a.error().message + ")";
  }
  return r;
}

inline std::unique_ptr<OperatorPanel> make_panel(const PanelContext& ctx) {
  switch (ctx.device.set_values) {
    case SetValues::saw: return std::make_unique<detail::SawPanel>(ctx);
    case SetValues::puller:
      return std::make_unique<detail::DrivePanel<linebridge_msgs::msg::PullerSetpointPubSubType>>(ctx);
    case SetValues::corrugator:
      return std::make_unique<detail::DrivePanel<linebridge_msgs::msg::CorrugatorSetpointPubSubType>>(ctx);
    case SetValues::winder:
      return std::make_unique<detail::DrivePanel<linebridge_msgs::msg::WinderSetpointPubSubType>>(ctx);
    case SetValues::loom: return std::make_unique<detail::LoomPanel>(ctx);
  }
  throw std::logic_error("unknown set-value type");
}

}  // namespace lb::test::safety
