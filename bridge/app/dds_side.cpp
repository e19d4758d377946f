#include "app/dds_side.hpp"

#include "app/dds_supervisor.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <map>
#include <memory>
#include <optional>
#include <thread>

#include "app/arguments.hpp"
#include "app/dds_options.hpp"
#include "app/observability/http_server.hpp"
#include "app/observability/line_view.hpp"
#include "app/run_until_signal.hpp"
#include "base/log_rate.hpp"
#include "dds/cdr.hpp"
#include "dds/channel_identity.hpp"
#include "dds/raw_type.hpp"
#include "dds/topic_names.hpp"
#include "link/dds_channel.hpp"

namespace lb::app {
namespace {

namespace fdds = eprosima::fastdds::dds;

// How long a relayed sample may wait for the bus side before it is dropped (and counted): a bus
// side that stalls that long has its own watchdog to answer to.
constexpr int kSendTimeoutMs = 200;
// The bus side pings every second; without one for this long its DDS side stops feeding its own
// watchdog (a DDS side cut off from its bus serves nothing true).
constexpr auto kBusSilence = std::chrono::seconds(3);
constexpr auto kConnectFor = std::chrono::seconds(10);
// Connected and not let in for this long: waiting is its state (a standby's bus side), say so.
constexpr auto kWaitingReadyAfter = std::chrono::seconds(5);
// How soon a stop signal is seen while samples stream (when none do, at every receive timeout).
constexpr auto kSignalCheckEvery = std::chrono::milliseconds(20);
// What the discovery gate held back is logged at most this often (a flood must not flood the log).
constexpr auto kGateNewsEvery = std::chrono::seconds(10);
// What it holds, when participants came or went since: for the journal, once a minute at most.
constexpr auto kGateSummaryEvery = std::chrono::seconds(60);

bool stop_pending() {
  const sigset_t set = stop_signals();
  const timespec zero{0, 0};
  return sigtimedwait(&set, nullptr, &zero) > 0;
}

class Relay {
 public:
  Relay(ddsl::Participant& dds, link::DdsChannel& channel, obs::LineViewKeeper& view, const std::string& line)
      : dds_(dds),
        channel_(channel),
        view_(view),
        diagnostics_topic_(ddsl::topic_name(line, ddsl::kBridgeNamespace, "diagnostics")) {}

  Result<void> declare(const link::Declare& d) {
    if (d.writer) {
      auto w = dds_.raw_writer(d);
      if (!w) return w.error();
      writers_[d.id] = *w;
      if (d.topic == diagnostics_topic_) diagnostics_id_ = d.id;
      return {};
    }
    // A reader of one bus's devices sends on that bus's lane (Declare::lane): straight to its loop.
    return dds_.subscribe_raw(d, [this, id = d.id, lane = d.lane](const std::vector<std::uint8_t>& cdr,
                                                                  const fdds::SampleInfo& info,
                                                                  std::vector<std::string> partitions) {
      link::Sample s;
      s.id = id;
      s.identity = ddsl::to_link(info.sample_identity);
      s.related = ddsl::to_link(info.related_sample_identity);
      s.partitions = std::move(partitions);
      s.payload = cdr;
      if (!channel_.send(lane, std::move(s))) not_forwarded_.fetch_add(1, std::memory_order_relaxed);
    });
  }

  void publish(link::Sample& s) {
    const auto it = writers_.find(s.id);
    if (it == writers_.end()) return;
    ++published_;
    // The line's diagnostics (once a second) feed the status page and the metrics; no other
    // sample is decoded here (status samples are the relay's hot path).
    if (s.id == diagnostics_id_) keep_diagnostics(s.payload);
    ddsl::RawSample raw{std::move(s.payload)};
    if (s.related == link::Identity{}) {
      it->second->write(&raw);
      return;
    }
    eprosima::fastrtps::rtps::WriteParams params;
    params.related_sample_identity(ddsl::from_link(s.related));
    it->second->write(&raw, params);
  }

  // Once a second: what the bus process is told, and what the status page and the metrics show.
  link::DdsStats stats() const {
    link::DdsStats st;
    st.samples_not_forwarded = not_forwarded_.load(std::memory_order_relaxed);
    const auto remote = dds_.remote_counts();
    st.remote_participants = static_cast<std::uint32_t>(std::max(0, remote.known));
    st.remote_participants_refused = remote.refused;
    view_.update([&](obs::LineView& v) {
      v.samples_published = published_;
      v.samples_not_forwarded = st.samples_not_forwarded;
      v.remote_participants = st.remote_participants;
      v.remote_participants_refused = remote.refused;
      v.remote_participants_departed = remote.departed;
      v.secured = dds_.secured();
      v.gate = dds_.gate_counts();
    });
    return st;
  }

 private:
  void keep_diagnostics(const std::vector<std::uint8_t>& cdr) {
    auto sample = std::make_shared<linebridge_msgs::msg::Diagnostics>();
    if (!ddsl::from_cdr(cdr, *sample)) {
      if (undecoded_.allow()) {
        spdlog::warn("observability: a diagnostics sample of {} bytes could not be decoded; the status page keeps "
                     "the previous one{}",
                     cdr.size(), held_back_note(undecoded_));
      }
      return;
    }
    const auto now = std::chrono::steady_clock::now();
    view_.update([&](obs::LineView& v) {
      v.diagnostics = std::move(sample);
      v.received = now;
    });
  }

  ddsl::Participant& dds_;
  link::DdsChannel& channel_;
  obs::LineViewKeeper& view_;
  std::string diagnostics_topic_;
  std::optional<std::uint32_t> diagnostics_id_;         // its writer, once declared
  std::map<std::uint32_t, fdds::DataWriter*> writers_;  // main thread only
  std::uint64_t published_ = 0;                         // main thread only
  std::atomic<std::uint64_t> not_forwarded_{0};
  LogRate undecoded_{1};
};

// The status page and metrics, when the line file wants them: a server that cannot listen is an
// error in the log, never the end of this process (the line's DDS side matters more than its page).
std::unique_ptr<obs::ObservabilityServer> start_observability(const profiles::ObservabilityConfig& config,
                                                              const obs::LineViewKeeper& view) {
  if (!config.enabled) {
    spdlog::info("observability: off (observability: listen: off): no status page, no metrics");
    return nullptr;
  }
  obs::ObservabilityServer::Options options;
  options.listen = config.listen();
  auto server = obs::ObservabilityServer::start(options, view);
  if (!server) {
    spdlog::error("observability: {}; this DDS side runs on without its status page and metrics",
                  server.error().message);
    return nullptr;
  }
  spdlog::info("observability: status page http://{}/ and metrics http://{}/metrics (read-only: GET){}",
               config.listen(), config.listen(),
               config.address == "127.0.0.1" || config.address == "::1" ? " on loopback only" : "");
  return std::move(*server);
}

}  // namespace

int run_dds_side(const ddsl::ParticipantOptions& options, const std::string& line,
                 const profiles::ObservabilityConfig& observability, const std::string& channel_path,
                 std::chrono::milliseconds duration) {
  if (!die_with_bus_process()) return kExitFailure;
  const auto started = std::chrono::steady_clock::now();
  // Discovery floods are bounded by the participant's discovery gate (dds/discovery_gate.hpp):
  // Fast DDS never holds more unauthenticated participants than its quotas (a participant
  // outnumbering the line's old bound ended this process, and any 33 honest ones did), and
  // authenticated ones are never limited by it: nothing on the network ends this process.
  auto dds = ddsl::Participant::create_checked(options);
  if (!dds) {
    spdlog::error("{}", dds.error().message);
    return dds.error().configuration ? kExitUsage : kExitFailure;
  }
  if (options.security) spdlog::info("{}", security_summary(options));
  // Before the channel: while this DDS side waits for its bus process (a standby's waits until it
  // masters a bus), the page says so.
  obs::LineViewKeeper view(line);
  const auto server = start_observability(observability, view);

  std::unique_ptr<link::DdsChannel> channel;
  uint64_t watchdog_usec = 0;
  const bool watchdog = sd_watchdog_enabled(0, &watchdog_usec) > 0;
  while (true) {
    auto c = link::connect_channel(channel_path, kSendTimeoutMs);
    if (c) {
      // Connected: the bus side accepts once its line is set up, and what it says then is its
      // answer; a refusal is final. A standby's bus side lets it in only when it masters a bus:
      // waiting connected is then this process's normal state, and a service manager is told so
      // (else systemd times its start out and starts another, again and again, on a standby PC).
      const auto connected = std::chrono::steady_clock::now();
      bool told_waiting = false;
      auto last_ping = connected;
      while (!channel) {
        auto greeted = link::DdsChannel::greet(*c, kSendTimeoutMs, 100);
        if (!greeted) {
          spdlog::error("channel {}: {}; this DDS side ends", channel_path, greeted.error().message);
          return kExitFailure;
        }
        channel = std::move(*greeted);
        if (!channel && stop_pending()) return kExitOk;
        const auto now = std::chrono::steady_clock::now();
        if (!channel && !told_waiting && now - connected >= kWaitingReadyAfter) {
          told_waiting = true;
          sd_notifyf(0,
                     "READY=1\nSTATUS=waiting to be let in by the bus process of line %s (a standby that does "
                     "not master a bus yet, or a line still being set up)",
                     line.c_str());
          spdlog::info("channel {}: connected, waiting to be let in (a standby bus side lets this DDS side in when "
                       "it masters a bus)",
                       channel_path);
        }
        if (told_waiting && watchdog && now - last_ping >= std::chrono::seconds(1)) {
          sd_notify(0, "WATCHDOG=1");
          last_ping = now;
        }
      }
      break;
    }
    if (std::chrono::steady_clock::now() - started > kConnectFor) {
      spdlog::error("no bus process on {}: {}", channel_path, c.error().message);
      return kExitFailure;
    }
    if (stop_pending()) return kExitOk;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }

  if (const auto& hello = channel->hello(); hello.line != line) {
    spdlog::error("channel {} serves line '{}', this DDS side is configured for '{}'", channel_path, hello.line, line);
    return kExitUsage;
  }
  spdlog::info("channel {}: bus process pid {} of line {}, {} lane(s)", channel_path, channel->hello().pid,
               channel->hello().line, channel->hello().lanes);

  const auto let_in = std::chrono::steady_clock::now();
  view.update([&](obs::LineView& v) {
    v.connected = true;
    v.connected_since = let_in;
  });
  Relay relay(**dds, *channel, view, line);
  auto last_ping = std::chrono::steady_clock::now();
  auto next_tick = last_ping;
  auto next_signal_check = last_ping;
  auto next_gate_news = last_ping;
  auto next_gate_summary = last_ping + kGateSummaryEvery;
  std::uint64_t summarized_admitted = 0;
  bool ready = false;
  std::size_t endpoints = 0;
  while (true) {
    const auto now = std::chrono::steady_clock::now();
    if (duration.count() > 0 && now - started >= duration) return kExitOk;
    // Not once per message: a system call per sample is what this loop's throughput is made of.
    if (now >= next_signal_check) {
      next_signal_check = now + kSignalCheckEvery;
      if (stop_pending()) {
        sd_notify(0, "STOPPING=1");
        return kExitOk;
      }
    }
    if (now >= next_tick) {
      next_tick = now + std::chrono::seconds(1);
      const auto stats = relay.stats();
      channel->send(stats);
      if (now >= next_gate_news) {
        next_gate_news = now + kGateNewsEvery;
        for (const auto& news : (*dds)->gate_news()) spdlog::warn("discovery: {}", news);
      }
      if (now >= next_gate_summary) {
        next_gate_summary = now + kGateSummaryEvery;
        const auto g = (*dds)->gate_counts();
        if (g.admitted != summarized_admitted) {
          summarized_admitted = g.admitted;
          spdlog::info("discovery: {} remote participant(s) {}, {} pending{}; since start {} let in, {} evicted, {} "
                       "message(s) dropped",
                       g.proven_now, (*dds)->secured() ? "authenticated" : "taking part", g.pending_now,
                       (*dds)->secured()
                           ? fmt::format(", {} handshake message(s) held (of Fast DDS's 100)", g.handshake_slots_now)
                           : std::string(),
                       g.admitted, g.evicted, g.dropped);
        }
      }
      if (watchdog && ready && now - last_ping < kBusSilence) sd_notify(0, "WATCHDOG=1");
    }
    auto message = channel->receive(100);
    if (!message) {
      spdlog::error("channel {}: {}; this DDS side ends (its supervisor starts another)", channel_path,
                    message.error().message);
      return kExitFailure;
    }
    if (!*message) continue;
    auto& m = **message;
    if (auto* declare = std::get_if<link::Declare>(&m)) {
      if (auto made = relay.declare(*declare); !made) {
        spdlog::error("{}", made.error().message);
        return (*dds)->secured() ? kExitUsage : kExitFailure;
      }
      ++endpoints;
    } else if (auto* sample = std::get_if<link::Sample>(&m)) {
      relay.publish(*sample);
    } else if (std::holds_alternative<link::Ready>(m)) {
      if (!ready) {
        ready = true;
        sd_notifyf(0, "READY=1\nSTATUS=%zu DDS endpoint(s) of line %s", endpoints, line.c_str());
        spdlog::info("DDS side of line {} ready: {} endpoint(s) on domain {}", line, endpoints, options.domain);
        // Once every endpoint exists: what the site's profiles set of them that is not applied.
        for (const auto& note : (*dds)->site_notes()) spdlog::warn("DDS profiles: {}", note);
      }
      last_ping = std::chrono::steady_clock::now();
    } else if (std::holds_alternative<link::Ping>(m)) {
      last_ping = std::chrono::steady_clock::now();
    }
  }
}

}  // namespace lb::app
