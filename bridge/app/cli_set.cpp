#include "app/cli_set.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <initializer_list>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

#include "app/boot_wait.hpp"
#include "app/cli_exit.hpp"
#include "base/result.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/codecs/drive_binding.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/feederPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "profiles/device_types.hpp"

namespace lb::app {

namespace msg = linebridge_msgs::msg;
using Clock = std::chrono::steady_clock;

namespace {

// Latest value of something a DDS thread delivers, waited for by the main thread.
template <class T>
class Mailbox {
 public:
  void put(const T& v) {
    {
      std::lock_guard lock(m_);
      value_ = v;
    }
    cv_.notify_all();
  }
  template <class Pred>
  std::optional<T> wait(Clock::duration timeout, Pred pred) {
    std::unique_lock lock(m_);
    if (!cv_.wait_for(lock, timeout, [&] { return value_ && pred(*value_); })) return std::nullopt;
    return value_;
  }

 private:
  std::mutex m_;
  std::condition_variable cv_;
  std::optional<T> value_;
};

bool wait_until(Clock::duration timeout, const std::function<bool()>& cond) {
  const auto end = Clock::now() + timeout;
  while (!cond()) {
    if (Clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

// The options a set value needs when nothing is in force yet and the command did not give them,
// as "--a, --b": empty when it may be sent.
std::string not_given(std::initializer_list<std::pair<bool, const char*>> options) {
  std::string out;
  for (const auto& [given, option] : options) {
    if (!given) out += (out.empty() ? "" : ", ") + std::string(option);
  }
  return out;
}

// A device whose status reports every set value 0 has none in force: none was given since the
// bridge started and none was kept from before (what a bridge sends until then). Its values then
// have nothing to keep, and a 0 taken from there (a 0 m length, a 0 % speed) would be a value
// nobody chose: the command must give them. Levels not given stay off, as they are.
Error nothing_in_force(const std::string& device, const std::string& missing) {
  return make_error(fmt::format("{}: no set values in force yet (its status reports them all 0: none was given since "
                                "the bridge started and none was kept from before), so the values not given have "
                                "nothing to keep: give {} too (nothing was sent)",
                                device, missing));
}

// The common path: the device's current status (online), then the set value, then its answer.
// make(status) builds the set value from what is in force, or says why it cannot (nothing sent);
// describe() says what was accepted.
template <class StatusPS, class SetpointPS>
int send_set_value(ddsl::Participant& dds, const std::string& line, const std::string& device,
                   const char* setpoint_name, const char* result_name, const SetOptions& o,
                   const std::function<Result<typename SetpointPS::type>(const typename StatusPS::type&)>& make,
                   const std::function<std::string(const typename SetpointPS::type&)>& describe) {
  using Status = typename StatusPS::type;
  const auto status_topic = ddsl::topic_name(line, device, "status");
  const auto result_topic = ddsl::topic_name(line, device, result_name);
  const auto setpoint_topic = ddsl::topic_name(line, device, setpoint_name);
  // One deadline for the whole command (online, boot, match, answer): --timeout bounds what the
  // user waits, not each step.
  const auto give_up = Clock::now() +
                       std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.timeout_s));
  const auto left = [&] { return std::max(Clock::duration::zero(), give_up - Clock::now()); };

  Mailbox<Status> status;
  Mailbox<msg::SetpointResult> result;
  auto writer = dds.writer<SetpointPS>(setpoint_topic, ddsl::QosKind::command);
  if (!writer) return fmt::print(stderr, "{}\n", writer.error().message), kExitNoAnswer;
  auto status_sub = dds.subscribe_scoped<StatusPS>(status_topic, ddsl::QosKind::state,
                                                   [&](const Status& s, const auto&) { status.put(s); });
  // Only the answer to this set value is kept: the mailbox holds one value, and other clients'
  // answers arriving right after it would otherwise replace it before it is looked at.
  const auto request_id = static_cast<std::uint64_t>(ddsl::now_ns());
  auto result_sub = dds.subscribe_scoped<msg::SetpointResultPubSubType>(result_topic, ddsl::QosKind::reply,
                                                                        [&](const msg::SetpointResult& r, const auto&) {
                                                                          if (r.request_id() == request_id)
                                                                            result.put(r);
                                                                        });
  if (!status_sub || !result_sub) {
    return fmt::print(stderr, "{}\n", !status_sub ? status_sub.error().message : result_sub.error().message),
           kExitNoAnswer;
  }
  // Fields not given keep the value in force, which the status topic reports; wait for the
  // device to be online so the bridge will not refuse the set value as offline.
  auto current = status.wait(left(), [](const Status& s) { return s.health().online(); });
  if (!current) {
    fmt::print(stderr, "{}: no online status on {} within {} s (is the bridge running and the device up?)\n", device,
               status_topic, o.timeout_s);
    return kExitNoAnswer;
  }
  // Online comes before the boot's end, and a set value that enables a device not yet configured
  // is refused: wait until the bridge's diagnostics say the boot passed (or settled).
  if (auto booted = wait_for_boot(dds, line, device, left()); !booted) {
    fmt::print(stderr, "{} within {} s\n", booted.error().message, o.timeout_s);
    return kExitNoAnswer;
  }
  if (!wait_until(left(), [&] { return writer->matched() > 0 && dds.matched_writers(result_topic) > 0; })) {
    fmt::print(stderr, "{}: the bridge does not subscribe {}\n", device, setpoint_topic);
    return kExitNoAnswer;
  }
  // What is in force now: the boot's start may have restored kept values since the first status.
  current = status.wait(left(), [](const Status& s) { return s.health().online(); }).value_or(*current);
  auto made = make(*current);
  if (!made) return fmt::print(stderr, "{}\n", made.error().message), kExitUsage;
  auto sp = *made;
  sp.request_id(request_id);
  // Asked again, the same set value with the same request id, every second until answered: Fast
  // DDS 2.9.1 can lose a writer's last sample after a burst of its others, and the answer to this
  // set value is the bridge's reply writer's last sample when other clients' answers came just
  // before it (seen: applied and answered by the bridge, never delivered here). A set value is
  // absolute, so applying it twice changes nothing.
  std::optional<msg::SetpointResult> reply;
  while (!reply && Clock::now() < give_up) {
    writer->write(sp);
    const auto wait = std::min<Clock::duration>(ddsl::kAskAgainAfter, give_up - Clock::now());
    reply = result.wait(wait, [](const msg::SetpointResult&) { return true; });  // only ours are put there
  }
  if (!reply)
    return fmt::print(stderr, "{}: no answer from the bridge within {} s\n", device, o.timeout_s), kExitNoAnswer;
  if (!reply->accepted())
    return fmt::print(stderr, "{}: set value refused: {}\n", device, reply->reason()), kExitRefused;
  fmt::print("{}: accepted: {}\n", device, describe(sp));
  return kExitOk;
}

bool on(const std::optional<std::string>& v, bool in_force, const char* on_word = "on") {
  return v ? *v == on_word : in_force;
}

int set_saw(ddsl::Participant& dds, const std::string& line, const std::string& device, const SetOptions& o) {
  return send_set_value<msg::SawStatusPubSubType, msg::SawSetpointPubSubType>(
      dds, line, device, "setpoint", "setpoint_result", o,
      [&o, &device](const msg::SawStatus& s) -> Result<msg::SawSetpoint> {
        // The fields a SawSetpoint carries (a button pressed just now is none of them).
        const auto& c = s.control_word();
        const bool in_force = c.saw_program_on() || c.wall_thickening() || c.count_mode() != msg::SMOOTH_PIPE ||
                              s.sync_speed_set_percent() != 0 || s.product_length_set_m() != 0;
        // A program switched off runs on nothing it carries: a stop is never held back.
        if (!in_force && o.program != "off") {
          const auto missing = not_given({{o.sync_speed_percent.has_value(), "--sync-speed-percent"},
                                          {o.product_length_m.has_value(), "--product-length-m"}});
          if (!missing.empty()) return nothing_in_force(device, missing);
        }
        msg::SawSetpoint sp;
        sp.saw_program_on(on(o.program, s.control_word().saw_program_on()));
        sp.wall_thickening(on(o.wall_thickening, s.control_word().wall_thickening()));
        sp.count_mode(o.count_mode ? (*o.count_mode == "corrugated" ? msg::CORRUGATED_PIPE : msg::SMOOTH_PIPE)
                                   : s.control_word().count_mode());
        sp.sync_speed_percent(o.sync_speed_percent.value_or(s.sync_speed_set_percent()));
        sp.product_length_m(o.product_length_m.value_or(s.product_length_set_m()));
        return sp;
      },
      [](const msg::SawSetpoint& sp) {
        return fmt::format("program {}, wall-thickening {}, {} pipe, sync speed {} %, product length {} m",
                           sp.saw_program_on() ? "on" : "off", sp.wall_thickening() ? "on" : "off",
                           sp.count_mode() == msg::CORRUGATED_PIPE ? "corrugated" : "smooth", sp.sync_speed_percent(),
                           sp.product_length_m());
      });
}

template <class StatusPS, class SetpointPS>
int set_drive(ddsl::Participant& dds, const std::string& line, const std::string& device, const SetOptions& o) {
  return send_set_value<StatusPS, SetpointPS>(
      dds, line, device, "setpoint", "setpoint_result", o,
      [&o, &device](const typename StatusPS::type& s) -> Result<typename SetpointPS::type> {
        const bool in_force = s.control_word().extruder_running() || s.speed_set_percent() != 0;
        if (!in_force && o.extruder != "stopped" && !o.speed_percent)
          return nothing_in_force(device, "--speed-percent");
        typename SetpointPS::type sp;
        sp.extruder_running(on(o.extruder, s.control_word().extruder_running(), "running"));
        sp.speed_set_percent(o.speed_percent.value_or(s.speed_set_percent()));
        return sp;
      },
      [](const typename SetpointPS::type& sp) {
        return fmt::format("extruder {}, speed {} %", sp.extruder_running() ? "running" : "stopped",
                           sp.speed_set_percent());
      });
}

int set_feeder(ddsl::Participant& dds, const std::string& line, const std::string& device, const SetOptions& o) {
  return send_set_value<msg::FeederStatusPubSubType, msg::LoomSetpointPubSubType>(
      dds, line, device, "loom", "loom_result", o,
      [&o, &device](const msg::FeederStatus& s) -> Result<msg::LoomSetpoint> {
        msg::LoomSetpoint sp;
        if (o.loom_status) {
          // RPDO2 in force: a loom status or a weft filling other than 0 (a loom stop carries none).
          const bool in_force = s.loom().loom_status().raw() != 0 || s.loom().weft_filling_raw() != 0;
          if (!in_force && *o.loom_status != "stop") {
            const auto missing = not_given({{o.maximum_speed_per_min.has_value(), "--maximum-speed"},
                                            {o.loom_width_m.has_value(), "--loom-width-m"}});
            if (!missing.empty()) return nothing_in_force(device, missing);
          }
          // RPDO2 carries the loom status with the weft filling: what is not given stays in force.
          sp.loom_status(*o.loom_status);
          sp.maximum_speed_per_min(
              static_cast<std::uint16_t>(o.maximum_speed_per_min.value_or(s.loom().maximum_speed_per_min())));
          sp.loom_width_m(o.loom_width_m.value_or(s.loom().loom_width_m()));
        }
        if (o.trigger_signal) sp.trigger_signal(*o.trigger_signal);
        for (auto p : o.picks) sp.pick_insertion().push_back(static_cast<std::uint8_t>(p));
        for (auto v : o.outputs) sp.digital_outputs().push_back(static_cast<std::uint8_t>(v));
        return sp;
      },
      [](const msg::LoomSetpoint& sp) {
        std::string out;
        if (!sp.loom_status().empty()) {
          out += fmt::format("loom {} at {} 1/min, width {} m; ", sp.loom_status(), sp.maximum_speed_per_min(),
                             sp.loom_width_m());
        }
        if (!sp.trigger_signal().empty()) out += "trigger " + sp.trigger_signal() + "; ";
        if (!sp.pick_insertion().empty()) out += fmt::format("picks [{:02X}]; ", fmt::join(sp.pick_insertion(), " "));
        if (!sp.digital_outputs().empty())
          out += fmt::format("outputs [{:02X}]; ", fmt::join(sp.digital_outputs(), " "));
        return out.substr(0, out.size() - 2);
      });
}

}  // namespace

std::string set_options_of(const std::string& device_type) {
  const auto* type = profiles::find_device_type(device_type);
  if (type == nullptr) return "none";
  switch (type->behaviour) {
    case profiles::Behaviour::saw:
      return "--program, --wall-thickening, --sync-speed-percent, --product-length-m, --count-mode";
    case profiles::Behaviour::feeder:
      return "--loom-status, --maximum-speed, --loom-width-m, --trigger-signal, --picks, --outputs";
    case profiles::Behaviour::drive: break;
  }
  return "--extruder, --speed-percent";
}

int run_set(ddsl::Participant& dds, const std::string& line, const std::string& device, const std::string& device_type,
            const SetOptions& o) {
  const auto* type = profiles::find_device_type(device_type);
  if (type != nullptr) {
    switch (type->behaviour) {
      case profiles::Behaviour::saw: return set_saw(dds, line, device, o);
      case profiles::Behaviour::feeder: return set_feeder(dds, line, device, o);
      case profiles::Behaviour::drive: {
        int rc = kExitUsage;
        if (gateways::visit_drive(type->idl, [&]<class Binding>() {
              rc = set_drive<typename Binding::StatusTopic, typename Binding::SetpointTopic>(dds, line, device, o);
            })) {
          return rc;
        }
        break;
      }
    }
  }
  fmt::print(stderr, "{}: no set values for a {}\n", device, device_type);
  return kExitUsage;
}

}  // namespace lb::app
