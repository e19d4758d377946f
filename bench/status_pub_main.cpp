// bench-status-pub: the bare DDS hop. Writes the saw status samples of one bench bus with Fast DDS
// alone, with the bridge's QoS, type and sample contents, at the rate and in the order the
// injector sends frames, each sample stamped as the bridge's would be after decoding that frame:
// the part of the bridge's CAN -> DDS latency that DDS costs by itself.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>

#include "clock.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/sawPubSubTypes.h"
#include "names.hpp"
#include "proc_stats.hpp"
#include "rendezvous.hpp"
#include "saw_stamps.hpp"
#include "security_option.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;

int main(int argc, char** argv) {
  CLI::App cli{"bench-status-pub: saw status samples from a bare Fast DDS writer"};
  int devices = 30;
  int domain = 0;
  double rate = 3000;
  std::uint64_t count = 10000;
  std::string ready_file, go_file, stop_file;
  double linger_s = 2;
  cli.add_option("--devices", devices, "saws (of bus 0)")->capture_default_str();
  cli.add_option("--domain", domain)->capture_default_str();
  cli.add_option("--rate", rate, "samples per second")->check(CLI::PositiveNumber)->capture_default_str();
  cli.add_option("--count", count, "samples")->capture_default_str();
  cli.add_option("--ready", ready_file, "created once every writer has a matched reader");
  cli.add_option("--go", go_file, "start writing once this file exists");
  cli.add_option("--stop", stop_file, "after writing, stay until this file exists (or --linger)");
  cli.add_option("--linger", linger_s, "at most this long after writing, seconds")->capture_default_str();
  bench::SecurityOption security;
  security.add(cli);
  CLI11_PARSE(cli, argc, argv);

  auto dds = lb::ddsl::Participant::create(security.options(domain, "bench-status-pub"));
  if (!dds) {
    std::fprintf(stderr, "bench-status-pub: %s\n", dds.error().message.c_str());
    return 1;
  }
  std::vector<lb::ddsl::Writer<msg::SawStatusPubSubType>> writers;
  std::vector<msg::SawStatus> samples(static_cast<std::size_t>(devices));
  for (int d = 0; d < devices; ++d) {
    auto w = (*dds)->writer<msg::SawStatusPubSubType>(lb::ddsl::topic_name(bench::kLine, bench::device_name(0, d), "status"),
                                                      lb::ddsl::QosKind::state);
    if (!w) {
      std::fprintf(stderr, "bench-status-pub: %s\n", w.error().message.c_str());
      return 1;
    }
    writers.push_back(*w);
    writers.back().write(samples[static_cast<std::size_t>(d)]);  // as the bridge: the device exists before its data
  }
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  for (const auto& w : writers) {
    while (w.matched() == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        std::fprintf(stderr, "bench-status-pub: no reader matched\n");
        return 1;
      }
      std::this_thread::sleep_for(10ms);
    }
  }
  bench::signal_file(ready_file);
  if (!bench::await_file(go_file, 300s)) return 1;

  std::vector<std::uint32_t> k(static_cast<std::size_t>(devices), 0);
  std::uint64_t refused = 0;
  bench::Pacer pacer(rate);
  const double cpu0 = bench::process_cpu_s();
  pacer.start();
  for (std::uint64_t i = 0; i < count; ++i) {
    pacer.wait(i);
    const auto d = static_cast<std::size_t>(i % static_cast<std::uint64_t>(devices));
    auto& s = samples[d];
    const auto stamp_ns = bench::realtime_ns();
    bench::apply_tpdo(s, ++k[d], bench::stamp32(stamp_ns));
    const auto st = lb::ddsl::to_stamp(stamp_ns);
    s.stamp().sec(st.sec);
    s.stamp().nanosec(st.nanosec);
    if (!writers[d].write(s)) ++refused;
  }
  const double elapsed = pacer.elapsed_s();
  const double cpu = bench::process_cpu_s() - cpu0;
  std::fputs(fmt::format("pub_written={}\npub_refused={}\npub_elapsed_s={:.3f}\npub_max_lag_ms={:.2f}\npub_cpu_pct={:.1f}\n",
                         count - refused, refused, elapsed, static_cast<double>(pacer.max_lag_ns()) / 1e6,
                         100 * cpu / elapsed)
                 .c_str(),
             stdout);
  std::fflush(stdout);
  // Reliable delivery of the last samples needs the writer alive.
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(linger_s);
  while (!bench::file_exists(stop_file) && std::chrono::steady_clock::now() < until) std::this_thread::sleep_for(10ms);
  return 0;
}
