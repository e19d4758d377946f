#include "app/cli_echo.hpp"

#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "app/cli_exit.hpp"
#include "app/common_text.hpp"
#include "app/drive_text.hpp"
#include "app/feeder_text.hpp"
#include "app/run_until_signal.hpp"
#include "app/saw_text.hpp"
#include "app/stdout_gone.hpp"
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

// stdout is gone (the reader of a pipe ended; SIGPIPE is ignored): end the echo as after a signal.
void flush_or_stop() {
  if (std::fflush(stdout) != 0 || std::ferror(stdout)) request_stop();
}

// Prints samples as they come, one at a time; status lines at most `rate` a second unless their
// key (status bits, online) changed.
class Printer {
 public:
  Printer(std::string device, double rate_hz)
      : device_(std::move(device)),
        min_gap_(std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / rate_hz))) {}

  void print(const std::string& text) {
    std::lock_guard lock(m_);
    // fputs, not fmt::print: a closed pipe must be an error to look at, not an exception on a DDS thread.
    std::fputs(fmt::format("{} {}\n", device_, text).c_str(), stdout);
    flush_or_stop();
  }
  void throttled(std::uint64_t key, const std::string& text) {
    const auto now = Clock::now();
    {
      std::lock_guard lock(m_);
      if (have_key_ && now - last_ < min_gap_ && key == last_key_) return;
      last_ = now;
      last_key_ = key;
      have_key_ = true;
    }
    print(text);
  }

 private:
  std::string device_;
  Clock::duration min_gap_;
  std::mutex m_;
  Clock::time_point last_{};
  std::uint64_t last_key_ = 0;
  bool have_key_ = false;
};

using Subscription = std::unique_ptr<ddsl::Participant::Subscription>;

// Scoped: the printer the callback uses must outlive it, and it lives in run_echo.
template <class PubSubType, class Render>
Result<Subscription> subscribe(ddsl::Participant& dds, const std::string& topic, ddsl::QosKind kind, Render render) {
  return dds.subscribe_scoped<PubSubType>(topic, kind,
                                          [render](const typename PubSubType::type& s, const auto&) { render(s); });
}

std::uint64_t status_key(const msg::DeviceHealth& h, std::uint16_t word) {
  return std::uint64_t{word} << 1 | (h.online() ? 1U : 0U);
}

Result<Subscription> subscribe_topic(ddsl::Participant& dds, const std::string& topic_name, const std::string& type,
                                     const std::string& topic, Printer& out) {
  using ddsl::QosKind;
  const auto text = [&out](const auto& s) { out.print(to_text(s)); };
  if (topic == "info") return subscribe<msg::DeviceInfoPubSubType>(dds, topic_name, QosKind::state, text);
  if (topic == "emergency") return subscribe<msg::EmergencyPubSubType>(dds, topic_name, QosKind::event, text);
  if (topic == "diagnostics") {
    return subscribe<msg::DiagnosticsPubSubType>(dds, topic_name, QosKind::state, [](const msg::Diagnostics& d) {
      std::fputs(to_text(d).c_str(), stdout), flush_or_stop();
    });
  }
  if (topic == "setpoint_result" || topic == "loom_result") {
    return subscribe<msg::SetpointResultPubSubType>(
        dds, topic_name, QosKind::reply, [&out](const msg::SetpointResult& r) {
          out.print(
              fmt::format("request {}: {}{}", r.request_id(), r.accepted() ? "accepted" : "refused: ", r.reason()));
        });
  }
  const auto* entry = profiles::find_device_type(type);
  const auto behaviour = entry != nullptr ? std::optional(entry->behaviour) : std::nullopt;
  if (behaviour == profiles::Behaviour::saw && topic == "status") {
    return subscribe<msg::SawStatusPubSubType>(dds, topic_name, QosKind::state, [&out](const msg::SawStatus& s) {
      out.throttled(status_key(s.health(), s.status_word().raw()), to_text(s));
    });
  }
  if (behaviour == profiles::Behaviour::saw && topic == "cut") {
    return subscribe<msg::SawCutPubSubType>(dds, topic_name, QosKind::event, text);
  }
  if (behaviour == profiles::Behaviour::drive && topic == "status") {
    std::optional<Result<Subscription>> sub;
    gateways::visit_drive(entry->idl, [&]<class Binding>() {
      using Status = typename Binding::Status;
      sub = subscribe<typename Binding::StatusTopic>(dds, topic_name, QosKind::state, [&out](const Status& s) {
        out.throttled(status_key(s.health(), s.status_word().raw()), drive_status_text<Binding>(s));
      });
    });
    if (sub) return std::move(*sub);
  }
  if (behaviour == profiles::Behaviour::feeder && topic == "status") {
    return subscribe<msg::FeederStatusPubSubType>(dds, topic_name, QosKind::state, [&out](const msg::FeederStatus& s) {
      out.throttled(status_key(s.health(), static_cast<std::uint16_t>(s.error_bitmap())), to_text(s));
    });
  }
  if (behaviour == profiles::Behaviour::feeder && topic == "unwinding") {
    return subscribe<msg::FeederUnwindingPubSubType>(dds, topic_name, QosKind::event, text);
  }
  if (behaviour == profiles::Behaviour::feeder && topic == "feeder_error") {
    return subscribe<msg::FeederErrorPubSubType>(dds, topic_name, QosKind::event, text);
  }
  return make_error("a " + type + " has no topic '" + topic + "' (" + echo_topics(type) + ")");
}

}  // namespace

std::string echo_topics(const std::string& device_type) {
  if (device_type == ddsl::kBridgeNamespace) return "diagnostics";
  const auto* type = profiles::find_device_type(device_type);
  if (type != nullptr && type->behaviour == profiles::Behaviour::saw)
    return "status, cut, setpoint_result, info, emergency";
  if (type != nullptr && type->behaviour == profiles::Behaviour::feeder) {
    return "status, unwinding, feeder_error, loom_result, info, emergency";
  }
  return "status, setpoint_result, info, emergency";
}

int run_echo(ddsl::Participant& dds, const std::string& line, const std::string& device, const std::string& device_type,
             const EchoOptions& o) {
  const auto topic = ddsl::topic_name(line, device, o.topic);
  Printer out(device, o.rate_hz);
  auto sub = subscribe_topic(dds, topic, device_type, o.topic, out);
  if (!sub) {
    fmt::print(stderr, "{}\n", sub.error().message);
    return kExitUsage;
  }
  // A bridge that is not there publishes nothing: say so instead of staying silent.
  std::atomic<bool> done{false};
  std::thread watch([&] {
    constexpr auto kPatience = std::chrono::seconds(3);
    const auto start = Clock::now();
    bool warned = false;
    while (!done) {
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
      if (stdout_gone()) request_stop();
      const bool matched = dds.matched_writers(topic) > 0;
      if (!matched && !warned && Clock::now() - start > kPatience) {
        fmt::print(stderr, "waiting for the bridge: nothing publishes {} (is linebridge running for line {}?)\n", topic,
                   line);
        warned = true;
      } else if (matched && warned) {
        fmt::print(stderr, "the bridge publishes {} now\n", topic);
        warned = false;
      }
    }
  });
  run_until_signal(std::chrono::milliseconds(static_cast<long>(o.duration_s * 1000)));
  done = true;
  watch.join();
  return kExitOk;
}

}  // namespace lb::app
