// bench-plant-participants: the honest crowd of a plant's DDS domain (issue 41 point 1): N
// applications reading one device's status through the product's client code (ddsl::Participant,
// the line file's site settings, each with an identity of the line's PKI when the line is
// secured), and M other applications on the same domain without any identity (ROS 2 nodes, other
// vendors' programs: on a secured line they can never be served by the bridge, only be there).
// Every --every seconds it prints how many samples the readers got and how many of them got at
// least one; at the end, which readers were never served. Runs until --duration or SIGTERM.
// Real UDP sockets: only inside launch_scripts/netns-run.sh.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <spdlog/spdlog.h>
#include "app/dds_options.hpp"
#include "app/line_config_source.hpp"

#include "dds/fastdds_log.hpp"
#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/routing/bridge_runs.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "profiles/profile_registry.hpp"
#include "stop_signals.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

struct Reader {
  std::unique_ptr<lb::ddsl::Participant> dds;
  std::atomic<std::uint64_t> samples{0};
  std::uint64_t seen_at_last_report = 0;
  std::atomic<std::int64_t> first_ms{-1};
};

int fail(const std::string& why) {
  std::fprintf(stderr, "bench-plant-participants: %s\n", why.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"N readers of a saw's status through the product's client code, M unsecured bystanders"};
  std::string config_path;
  std::vector<std::string> identities;
  int readers_count = 40;
  int bystanders = 0;
  std::string device = "saw1";
  double duration_s = 60;
  double every_s = 5;
  int start_interval_ms = 20;
  int service_every_ms = 0;
  bool fastdds_log = false;
  cli.add_option("--config", config_path, "the line file (its dds: keys, as linebridge-cli reads them)")->required();
  cli.add_option("--identity", identities,
                 "identity folders (pki.sh issue) the readers take in turn; required on a secured line");
  cli.add_option("--participants", readers_count, "readers of the status")->check(CLI::Range(0, 400));
  cli.add_option("--bystanders", bystanders, "participants without an identity (they read the same topic)")
      ->check(CLI::Range(0, 400));
  cli.add_option("--device", device, "a saw of the line")->capture_default_str();
  cli.add_option("--duration", duration_s, "seconds after the last participant was created")->capture_default_str();
  cli.add_option("--every", every_s, "report period, seconds")->capture_default_str();
  cli.add_option("--start-interval-ms", start_interval_ms, "pause between two participants' creation")
      ->capture_default_str();
  cli.add_option("--service-every-ms", service_every_ms,
                 "the first reader also reads the saw's 1000h through the product's ServiceClient this often "
                 "(one call at a time, each given the period to be answered)");
  cli.add_flag("--fastdds-log", fastdds_log, "Fast DDS's warnings and errors on stderr (rate-limited)");
  CLI11_PARSE(cli, argc, argv);
  std::optional<lb::ddsl::FastDdsLogRoute> route;
  if (fastdds_log) route.emplace();
  spdlog::set_level(spdlog::level::warn);
  if (std::getenv("LINEBRIDGE_NETNS") == nullptr) return fail("run through launch_scripts/netns-run.sh");
  lb::bench::StopSignals stop;

  const auto registry = lb::profiles::ProfileRegistry::builtin();
  auto line = lb::app::load_config(config_path, registry);
  if (!line) return fail(line.error().message);
  if (line->dds.security && identities.empty() && readers_count > 0)
    return fail("the line is secured: give the readers --identity");
  auto plain_line = *line;
  plain_line.dds.security.reset();
  const auto topic = lb::ddsl::topic_name(line->line, device, "status");

  const auto started = Clock::now();
  const auto ms_since = [&started] {
    return std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - started).count();
  };
  std::vector<std::unique_ptr<Reader>> readers;
  std::vector<std::unique_ptr<lb::ddsl::Participant>> others;
  for (int i = 0; i < readers_count + bystanders && !stop.requested(); ++i) {
    const bool reader = i < readers_count;
    const auto name = fmt::format("{}-{}", reader ? "plant-reader" : "plant-bystander", i);
    auto options = reader ? lb::app::client_participant_options(
                                *line, name,
                                line->dds.security ? identities[static_cast<std::size_t>(i) % identities.size()] : "")
                          : lb::app::client_participant_options(plain_line, name, "");
    if (!options) return fail(options.error().message);
    auto dds = lb::ddsl::Participant::create(*options);
    if (!dds) return fail(dds.error().message);
    if (reader) {
      auto r = std::make_unique<Reader>();
      auto* raw = r.get();
      auto s = (*dds)->subscribe<msg::SawStatusPubSubType>(topic, lb::ddsl::QosKind::state,
                                                           [raw, &ms_since](const msg::SawStatus&, const auto&) {
                                                             if (raw->samples.fetch_add(1) == 0)
                                                               raw->first_ms = ms_since();
                                                           });
      if (!s) return fail(s.error().message);
      r->dds = std::move(*dds);
      readers.push_back(std::move(r));
    } else {
      // A bystander reads too (a ROS 2 node of the same names would): it costs the bridge what it costs.
      auto s = (*dds)->subscribe<msg::SawStatusPubSubType>(topic, lb::ddsl::QosKind::state,
                                                           [](const msg::SawStatus&, const auto&) {});
      if (!s) return fail(s.error().message);
      others.push_back(std::move(*dds));
    }
    if (start_interval_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(start_interval_ms));
  }
  std::printf("created_ms=%lld readers=%zu bystanders=%zu\n", static_cast<long long>(ms_since()), readers.size(),
              others.size());
  std::fflush(stdout);

  // An application's service client as the product's code makes one: created once, called for the
  // whole run (never re-created), each call given one period to be answered.
  std::atomic<std::uint64_t> asked{0}, answered{0};
  std::atomic<bool> calling{true};
  std::thread service;
  if (service_every_ms > 0 && !readers.empty()) {
    using ReadClient = lb::ddsl::ServiceClient<srv::SdoRead_RequestPubSubType, srv::SdoRead_ResponsePubSubType>;
    auto client = ReadClient::create(*readers.front()->dds, lb::ddsl::line_service_path(line->line, "sdo_read"),
                                     lb::gateways::bridge_runs(line->line));
    if (!client) return fail(client.error().message);
    service = std::thread([&, c = std::move(*client)] {
      srv::SdoRead_Request req;
      req.device(device);
      req.index(0x1000);
      req.sub_index(0);
      req.data_type("UNSIGNED32");
      const auto period = std::chrono::milliseconds(service_every_ms);
      auto next = Clock::now();
      while (calling) {
        ++asked;
        auto r = c->call(req, period);
        if (r && r->success()) ++answered;
        next += period;
        std::this_thread::sleep_until(next);
        if (Clock::now() > next + period) next = Clock::now();  // a call that overran does not make a burst
      }
    });
  }
  std::uint64_t asked_before = 0, answered_before = 0;

  const auto created = Clock::now();
  auto next_report = created + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(every_s));
  while (!stop.requested() && Clock::now() - created < std::chrono::duration<double>(duration_s)) {
    std::this_thread::sleep_for(50ms);
    if (Clock::now() < next_report) continue;
    next_report += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(every_s));
    std::uint64_t total = 0;
    int served = 0;
    for (auto& r : readers) {
      const auto now = r->samples.load();
      total += now - r->seen_at_last_report;
      if (now > r->seen_at_last_report) ++served;
      r->seen_at_last_report = now;
    }
    const auto a = asked.load(), b = answered.load();
    std::printf("at=%.3f t_s=%.0f samples=%llu served=%d/%zu answered=%llu/%llu known0=%d\n",
                std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(),
                ms_since() / 1000.0, static_cast<unsigned long long>(total), served, readers.size(),
                static_cast<unsigned long long>(b - answered_before), static_cast<unsigned long long>(a - asked_before),
                readers.empty() ? -1 : readers.front()->dds->remote_counts().known);
    asked_before = a;
    answered_before = b;
    std::fflush(stdout);
  }
  calling = false;
  if (service.joinable()) service.join();
  int never = 0;
  std::int64_t first_max = 0;
  for (std::size_t i = 0; i < readers.size(); ++i) {
    if (readers[i]->samples == 0) {
      ++never;
      std::printf("never_served=plant-reader-%zu\n", i);
    }
    first_max = std::max<std::int64_t>(first_max, readers[i]->first_ms);
  }
  std::printf("readers=%zu readers_never_served=%d first_sample_latest_ms=%lld\n", readers.size(), never,
              static_cast<long long>(first_max));
  return 0;
}
