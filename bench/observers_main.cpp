// bench-observers: N observer applications in one process (issue 25 'Why' 5: "20 observer
// participants raised the bridge's CPU tenfold"). Each is a participant of its own (secured with
// --pki/--identity when given) subscribed to every status topic of the bench line: each saw's
// status and emergency, and the bridge's diagnostics. They read and count, nothing else; they run
// until SIGTERM/SIGINT, then print what they saw.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "program.hpp"
#include "security_option.hpp"
#include "stop_signals.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;

int main(int argc, char** argv) {
  bench::Program program{"bench-observers", "N observer participants reading every status topic of the bench line"};
  auto& cli = program.cli;
  int count = 20;
  cli.add_option("--participants", count, "observer participants")->check(CLI::Range(1, 200))->capture_default_str();
  program.add_devices("saws on bus 0");
  program.add_domain();
  program.add_ready("every observer has a matched writer on every saw's status topic");
  program.add_security();
  if (auto rc = program.parse(argc, argv)) return *rc;
  const int devices = program.devices;
  bench::StopSignals stop;  // before the participants' threads start

  std::atomic<std::uint64_t> samples{0};
  std::vector<std::unique_ptr<lb::ddsl::Participant>> observers;
  std::vector<std::string> status_topics;
  for (int d = 0; d < devices; ++d)
    status_topics.push_back(lb::ddsl::topic_name(bench::kLine, bench::device_name(0, d), "status"));
  for (int i = 0; i < count; ++i) {
    auto dds = lb::ddsl::Participant::create(bench::participant_options(program, fmt::format("bench-observer-{}", i)));
    if (!dds) return program.fail(dds.error().message);
    for (int d = 0; d < devices; ++d) {
      auto s = (*dds)->subscribe<msg::SawStatusPubSubType>(status_topics[static_cast<std::size_t>(d)],
                                                           lb::ddsl::QosKind::state,
                                                           [&samples](const msg::SawStatus&, const auto&) {
                                                             ++samples;
                                                           });
      auto e = (*dds)->subscribe<msg::EmergencyPubSubType>(
          lb::ddsl::topic_name(bench::kLine, bench::device_name(0, d), "emergency"), lb::ddsl::QosKind::event,
          [&samples](const msg::Emergency&, const auto&) { ++samples; });
      if (!s || !e) {
        return program.fail((!s ? s.error() : e.error()).message);
      }
    }
    auto g = (*dds)->subscribe<msg::DiagnosticsPubSubType>(lb::ddsl::topic_name(bench::kLine, "bridge", "diagnostics"),
                                                           lb::ddsl::QosKind::state,
                                                           [&samples](const msg::Diagnostics&, const auto&) {
                                                             ++samples;
                                                           });
    if (!g) return program.fail(g.error().message);
    observers.push_back(std::move(*dds));
  }
  bool ready = false;
  const auto started = std::chrono::steady_clock::now();
  while (!stop.requested()) {
    if (!ready) {
      bool matched = true;
      for (auto& o : observers) {
        for (const auto& t : status_topics) matched = matched && o->matched_writers(t) > 0;
      }
      if (matched) {
        ready = true;
        std::printf("observers_matched_after_ms=%lld\n",
                    static_cast<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(
                                               std::chrono::steady_clock::now() - started)
                                               .count()));
        std::fflush(stdout);
        program.ready();
      }
    }
    std::this_thread::sleep_for(100ms);
  }
  std::printf("observers=%d\nobservers_ready=%d\nobservers_samples=%llu\n", count, ready ? 1 : 0,
              static_cast<unsigned long long>(samples.load()));
  return 0;
}
