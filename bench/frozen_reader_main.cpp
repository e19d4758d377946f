// bench-frozen-reader: an application that subscribes to the emergency events of every saw of the
// bench line (reliable, as the contract has them) and then freezes: after --freeze-after seconds
// it stops itself (SIGSTOP), so it neither reads nor acknowledges any more, as a hung HMI does.
// The bench script kills it at the end of the step.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <thread>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "program.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;

int main(int argc, char** argv) {
  bench::Program program{"bench-frozen-reader", "reads the bench line's emergencies, then freezes"};
  auto& cli = program.cli;
  double freeze_after_s = 3;
  program.add_devices("saws on bus 0");
  program.add_domain();
  cli.add_option("--freeze-after", freeze_after_s, "seconds of normal reading first")->capture_default_str();
  if (auto rc = program.parse(argc, argv)) return *rc;
  const int devices = program.devices;
  const int domain = program.domain;

  auto dds = lb::ddsl::Participant::create({static_cast<std::uint32_t>(domain), true, "bench-frozen-reader"});
  if (!dds) return program.fail(dds.error().message);
  std::atomic<std::uint64_t> seen{0};
  for (int d = 0; d < devices; ++d) {
    const auto topic = lb::ddsl::topic_name(bench::kLine, bench::device_name(0, d), "emergency");
    if (auto r = (*dds)->subscribe<msg::EmergencyPubSubType>(topic, lb::ddsl::QosKind::event,
                                                             [&seen](const msg::Emergency&, const auto&) { ++seen; });
        !r) {
      std::fprintf(stderr, "bench-frozen-reader: %s\n", r.error().message.c_str());
      return 1;
    }
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(freeze_after_s));
  std::fputs(fmt::format("frozen_reader_seen_before_freeze={}\n", seen.load()).c_str(), stdout);
  std::fflush(stdout);
  std::raise(SIGSTOP);
  return 0;
}
