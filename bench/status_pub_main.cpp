// bench-status-pub: the bare DDS hop. Writes the saw status samples of one bench bus with Fast DDS
// alone, with the bridge's QoS, type and sample contents, at the rate and in the order the
// injector sends frames, each sample stamped as the bridge's would be after decoding that frame:
// the part of the bridge's CAN -> DDS latency that DDS costs by itself.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <thread>
#include <vector>

#include "clock.hpp"
#include "dds/participant.hpp"
#include "proc_stats.hpp"
#include "program.hpp"
#include "saw_stamps.hpp"
#include "security_option.hpp"
#include "status_writers.hpp"

namespace bench = lb::bench;
using namespace std::chrono_literals;

int main(int argc, char** argv) {
  bench::Program program{"bench-status-pub", "saw status samples from a bare Fast DDS writer"};
  program.add_devices("saws on bus 0");
  program.add_domain();
  program.add_load("samples per second", "samples");
  program.add_ready("every writer has a matched reader");
  program.add_go("start writing");
  program.add_stop("writing");
  program.add_security();
  if (auto rc = program.parse(argc, argv)) return *rc;
  const int devices = program.devices;
  const double rate = program.rate;
  const std::uint64_t count = program.count;

  auto dds = lb::ddsl::Participant::create(bench::participant_options(program, program.name()));
  if (!dds) return program.fail(dds.error().message);
  auto status = bench::status_writers(**dds, devices);
  if (!status) return program.fail(status.error().message);
  auto& [writers, samples] = *status;
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  for (const auto& w : writers) {
    while (w.matched() == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        return program.fail("no reader matched");
      }
      std::this_thread::sleep_for(10ms);
    }
  }
  program.ready();
  if (!program.go()) return 1;

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
  std::fputs(
      fmt::format("pub_written={}\npub_refused={}\npub_elapsed_s={:.3f}\npub_max_lag_ms={:.2f}\npub_cpu_pct={:.1f}\n",
                  count - refused, refused, elapsed, static_cast<double>(pacer.max_lag_ns()) / 1e6, 100 * cpu / elapsed)
          .c_str(),
      stdout);
  std::fflush(stdout);
  program.linger();  // reliable delivery of the last samples needs the writer alive
  return 0;
}
