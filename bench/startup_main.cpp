// bench-startup: start-up time of a bridge process, from the moment it is spawned to the first
// status sample an application receives (and to the last device's first sample; with --online and
// a simulator playing the devices, also to the first samples with live data), with the
// application's participant and readers already up, as on a running line. Also reports the
// bridge's resident memory once it has settled, then stops it with SIGTERM; and the CPU each part
// used from the spawn until every device's first sample (--online: every device online): the bus
// process, its DDS process, this subscriber, and the process --watch-pid names (the simulator),
// which on a machine of few cores is what the start-up shares them with. And when this application
// discovered the bridge's DDS participant and its first and last status writer: a slow start's
// time is then placed in discovery or after it.
#include <fmt/format.h>
#include <sys/wait.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <fstream>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "clock.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/sawPubSubTypes.h"
#include "proc_stats.hpp"
#include "program.hpp"
#include "security_option.hpp"
#include "support/child_process.hpp"  // the tests' way to start a program, log to a file, stop it

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;

namespace {

struct FirstSamples {
  std::mutex m;
  std::condition_variable cv;
  std::size_t devices_seen = 0;
  std::int64_t first_ns = 0;
  std::int64_t all_ns = 0;
  std::vector<bool> seen;
  // The same for samples with live data: the device online (heartbeat seen, booted by the bridge).
  std::size_t devices_online = 0;
  std::int64_t first_online_ns = 0;
  std::int64_t all_online_ns = 0;
  std::vector<std::int64_t> online_at;  // per device: when its first live sample came (0: not yet)
};

// When this application learnt of the bridge's DDS side: its participant, then its devices'
// status writers (discovery, before any sample), so that a slow start is told apart by its phase.
struct Discovered {
  std::mutex m;
  std::set<std::string> status_topics;  // the ones this application reads
  std::set<std::string> writers_seen;   // of those topics
  std::int64_t participant_ns = 0;
  std::int64_t first_writer_ns = 0;
  std::int64_t all_writers_ns = 0;
};

// When the devices came online, ms after t0: the p-th percentile over all of them (every one online).
double online_percentile_ms(std::vector<std::int64_t> at, double p, std::int64_t t0) {
  std::sort(at.begin(), at.end());
  const auto i = static_cast<std::size_t>(p / 100.0 * static_cast<double>(at.size() - 1) + 0.5);
  return static_cast<double>(at[i] - t0) / 1e6;
}

}  // namespace

int main(int argc, char** argv) {
  bench::Program program{"bench-startup", "from process start to the first status sample"};
  auto& cli = program.cli;
  program.devices = 1;
  double timeout_s = 30;
  double settle_s = 2;
  int quiet_ms = 500;
  std::string log = "/dev/null";
  std::vector<std::string> command;
  program.add_buses();
  program.add_devices("saws per bus");
  program.add_domain();
  cli.add_option("--timeout", timeout_s)->capture_default_str();
  cli.add_option("--settle", settle_s, "seconds after the last first sample before reading memory")
      ->capture_default_str();
  cli.add_option("--quiet-ms", quiet_ms, "wait this long after subscribing before starting the bridge")
      ->capture_default_str();
  cli.add_option("--log", log, "the bridge's output")->capture_default_str();
  bool online = false;
  cli.add_flag("--online", online, "also wait for every device's first sample with live data (a simulator plays them)");
  cli.add_option("command", command, "the bridge command line (after --)")->required();
  int watched = 0;
  cli.add_option("--watch-pid", watched, "also report the CPU this process used over the start (the simulator)");
  program.add_security();
  if (auto rc = program.parse(argc, argv)) return *rc;
  const int buses = program.buses;
  const int devices = program.devices;

  FirstSamples first;  // outlives the participant's listeners
  first.seen.assign(static_cast<std::size_t>(buses * devices), false);
  first.online_at.assign(first.seen.size(), 0);
  std::vector<std::string> status_topics;  // by device index, bus by bus
  for (int b = 0; b < buses; ++b) {
    for (int d = 0; d < devices; ++d) {
      status_topics.push_back(lb::ddsl::topic_name(bench::kLine, bench::device_name(b, d), "status"));
    }
  }
  Discovered discovered;  // outlives the participant's listener too
  discovered.status_topics.insert(status_topics.begin(), status_topics.end());
  auto options = bench::participant_options(program, program.name());
  options.on_discovery = [&discovered](const lb::ddsl::DiscoveryEvent& e) {
    if (e.removed) return;
    const auto now = bench::realtime_ns();
    std::lock_guard lock(discovered.m);
    if (e.kind == lb::ddsl::DiscoveryEvent::Kind::participant) {
      if (discovered.participant_ns == 0) discovered.participant_ns = now;
    } else if (e.kind == lb::ddsl::DiscoveryEvent::Kind::writer && discovered.status_topics.contains(e.name) &&
               discovered.writers_seen.insert(e.name).second) {
      if (discovered.writers_seen.size() == 1) discovered.first_writer_ns = now;
      if (discovered.writers_seen.size() == discovered.status_topics.size()) discovered.all_writers_ns = now;
    }
  };
  auto dds = lb::ddsl::Participant::create(options);
  if (!dds) return program.fail(dds.error().message);
  for (std::size_t index = 0; index < status_topics.size(); ++index) {
    auto sub = (*dds)->subscribe<msg::SawStatusPubSubType>(status_topics[index], lb::ddsl::QosKind::state,
                                                           [&first, index](const msg::SawStatus& s,
                                                                           const lb::ddsl::fdds::SampleInfo&) {
                                                             const auto now = bench::realtime_ns();
                                                             std::lock_guard lock(first.m);
                                                             if (!first.seen[index]) {
                                                               first.seen[index] = true;
                                                               if (first.devices_seen++ == 0) first.first_ns = now;
                                                               if (first.devices_seen == first.seen.size())
                                                                 first.all_ns = now;
                                                             }
                                                             if (s.health().online() && first.online_at[index] == 0) {
                                                               first.online_at[index] = now;
                                                               if (first.devices_online++ == 0)
                                                                 first.first_online_ns = now;
                                                               if (first.devices_online == first.online_at.size())
                                                                 first.all_online_ns = now;
                                                             }
                                                             first.cv.notify_all();
                                                           });
    if (!sub) return program.fail(sub.error().message);
  }
  // By default our own initial announcements are over: the bridge finds a running application.
  std::this_thread::sleep_for(std::chrono::milliseconds(quiet_ms));

  const std::int64_t watched_cpu0 = watched > 0 ? bench::read_cpu_ns(watched) : 0;
  const double own_cpu0 = bench::process_cpu_s();
  const auto t0 = bench::realtime_ns();
  lb::test::ChildProcess bridge(command, log);
  if (!bridge.started()) return program.fail("cannot start " + command.front());
  bool all = false;
  {
    std::unique_lock lock(first.m);
    all = first.cv.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] {
      return first.devices_seen == first.seen.size() && (!online || first.devices_online == first.online_at.size());
    });
  }
  // Read at once, while every thread of the start still runs (read_cpu_ns counts live threads).
  const auto cpu_window_ns = bench::realtime_ns() - t0;
  const auto bus_cpu_ns = bench::read_cpu_ns(bridge.pid());
  std::int64_t dds_cpu_ns = 0;
  for (const pid_t c : bench::children_of(bridge.pid())) dds_cpu_ns += bench::read_cpu_ns(c);
  const std::int64_t watched_cpu_ns = watched > 0 ? bench::read_cpu_ns(watched) - watched_cpu0 : 0;
  const double own_cpu_s = bench::process_cpu_s() - own_cpu0;
  std::this_thread::sleep_for(std::chrono::duration<double>(settle_s));
  const auto mem = bench::read_tree_memory(bridge.pid());  // the bus process and its DDS process
  const int status = bridge.stop();                        // SIGTERM (SIGKILL if it has not ended 5 s later)

  std::string report;
  {
    // This application knows no other participant before the spawn (its own namespace).
    std::lock_guard lock(discovered.m);
    const auto after = [t0](std::int64_t ns) { return static_cast<double>(ns - t0) / 1e6; };
    if (discovered.participant_ns > 0)
      report += fmt::format("startup_found_dds_ms={:.1f}\n", after(discovered.participant_ns));
    if (discovered.first_writer_ns > 0) {
      report += fmt::format("startup_found_first_status_writer_ms={:.1f}\n", after(discovered.first_writer_ns));
    }
    if (discovered.all_writers_ns > 0) {
      report += fmt::format("startup_found_all_status_writers_ms={:.1f}\n", after(discovered.all_writers_ns));
    }
  }
  std::lock_guard lock(first.m);
  report += fmt::format("startup_devices={}\nstartup_devices_seen={}\n", first.seen.size(), first.devices_seen);
  if (first.devices_seen > 0)
    report += fmt::format("startup_first_ms={:.1f}\n", static_cast<double>(first.first_ns - t0) / 1e6);
  if (first.devices_seen == first.seen.size()) {
    report += fmt::format("startup_all_ms={:.1f}\n", static_cast<double>(first.all_ns - t0) / 1e6);
  }
  if (first.devices_online > 0) {
    report += fmt::format("startup_first_online_ms={:.1f}\n", static_cast<double>(first.first_online_ns - t0) / 1e6);
  }
  if (first.devices_online == first.online_at.size()) {
    report += fmt::format("startup_all_online_ms={:.1f}\n", static_cast<double>(first.all_online_ns - t0) / 1e6);
    // The devices' boot times: they boot side by side, so the spread says whether any waited for another.
    for (const double p : {10.0, 50.0, 90.0}) {
      report += fmt::format("startup_online_p{:.0f}_ms={:.1f}\n", p, online_percentile_ms(first.online_at, p, t0));
    }
  }
  if (all) {
    report += fmt::format("startup_cpu_window_ms={:.1f}\nstartup_cpu_bus_ms={:.1f}\nstartup_cpu_dds_ms={:.1f}\n"
                          "startup_cpu_sub_ms={:.1f}\n",
                          static_cast<double>(cpu_window_ns) / 1e6, static_cast<double>(bus_cpu_ns) / 1e6,
                          static_cast<double>(dds_cpu_ns) / 1e6, own_cpu_s * 1e3);
    if (watched > 0)
      report += fmt::format("startup_cpu_watched_ms={:.1f}\n", static_cast<double>(watched_cpu_ns) / 1e6);
  }
  report += fmt::format("startup_rss_kib={}\nstartup_hwm_kib={}\nstartup_pss_kib={}\nstartup_exit={}\n", mem.rss_kib,
                        mem.hwm_kib, mem.pss_kib, WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status));
  std::fputs(report.c_str(), stdout);
  return all ? 0 : 3;
}
