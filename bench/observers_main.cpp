// bench-observers: N observer applications in one process (issue 25 'Why' 5: "20 observer
// participants raised the bridge's CPU tenfold"). Each is a participant of its own (secured with
// --pki/--identity when given) subscribed to every status topic of the bench line: each saw's
// status and emergency, and the bridge's diagnostics. They read and count, nothing else; they run
// until SIGTERM/SIGINT, then print what they saw.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <memory>
#include <thread>
#include <vector>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "names.hpp"
#include "security_option.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;

namespace {
std::atomic<bool> stop_requested{false};
void on_signal(int) { stop_requested = true; }
}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"bench-observers: N observer participants reading every status topic of the bench line"};
  int count = 20;
  int devices = 30;
  int domain = 0;
  std::string ready_file;
  lb::bench::SecurityOption security;
  cli.add_option("--participants", count, "observer participants")->check(CLI::Range(1, 200))->capture_default_str();
  cli.add_option("--devices", devices, "saws on bus 0")->check(CLI::Range(1, bench::kMaxDevicesPerBus))->capture_default_str();
  cli.add_option("--domain", domain)->check(CLI::Range(0, 232))->capture_default_str();
  cli.add_option("--ready", ready_file, "created once every observer has a matched writer on every saw's status topic");
  security.add(cli);
  CLI11_PARSE(cli, argc, argv);
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);

  std::atomic<std::uint64_t> samples{0};
  std::vector<std::unique_ptr<lb::ddsl::Participant>> observers;
  std::vector<std::string> status_topics;
  for (int d = 0; d < devices; ++d) status_topics.push_back(lb::ddsl::topic_name(bench::kLine, bench::device_name(0, d), "status"));
  for (int i = 0; i < count; ++i) {
    auto dds = lb::ddsl::Participant::create(security.options(domain, fmt::format("bench-observer-{}", i)));
    if (!dds) {
      std::fprintf(stderr, "bench-observers: %s\n", dds.error().message.c_str());
      return 1;
    }
    for (int d = 0; d < devices; ++d) {
      auto s = (*dds)->subscribe<msg::SawStatusPubSubType>(status_topics[static_cast<std::size_t>(d)], lb::ddsl::QosKind::state,
                                                           [&samples](const msg::SawStatus&, const auto&) { ++samples; });
      auto e = (*dds)->subscribe<msg::EmergencyPubSubType>(lb::ddsl::topic_name(bench::kLine, bench::device_name(0, d), "emergency"),
                                                           lb::ddsl::QosKind::event,
                                                           [&samples](const msg::Emergency&, const auto&) { ++samples; });
      if (!s || !e) {
        std::fprintf(stderr, "bench-observers: %s\n", (!s ? s.error() : e.error()).message.c_str());
        return 1;
      }
    }
    auto g = (*dds)->subscribe<msg::DiagnosticsPubSubType>(lb::ddsl::topic_name(bench::kLine, "bridge", "diagnostics"),
                                                           lb::ddsl::QosKind::state,
                                                           [&samples](const msg::Diagnostics&, const auto&) { ++samples; });
    if (!g) {
      std::fprintf(stderr, "bench-observers: %s\n", g.error().message.c_str());
      return 1;
    }
    observers.push_back(std::move(*dds));
  }
  bool ready = false;
  const auto started = std::chrono::steady_clock::now();
  while (!stop_requested) {
    if (!ready) {
      bool matched = true;
      for (auto& o : observers) {
        for (const auto& t : status_topics) matched = matched && o->matched_writers(t) > 0;
      }
      if (matched) {
        ready = true;
        std::printf("observers_matched_after_ms=%lld\n",
                    static_cast<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - started).count()));
        std::fflush(stdout);
        if (!ready_file.empty()) std::ofstream(ready_file) << "ready\n";
      }
    }
    std::this_thread::sleep_for(100ms);
  }
  std::printf("observers=%d\nobservers_ready=%d\nobservers_samples=%llu\n", count, ready ? 1 : 0,
              static_cast<unsigned long long>(samples.load()));
  return 0;
}
