// bench-status-sub: the application end of CAN -> DDS. Subscribes to the status of every saw of
// the bench line (and to the bridge's diagnostics), times every sample from the send stamp its
// frame carried (saw_stamps.hpp) to the moment the listener takes it, and counts what arrived:
// frames the bridge did not get show in its diagnostics, samples lost between bridge and
// application show as a shortfall here.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <thread>
#include <vector>

#include "clock.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "latencies.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "program.hpp"
#include "saw_stamps.hpp"
#include "security_option.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

// Shared by the listener threads of every reader.
struct Tally {
  std::mutex m;
  std::condition_variable cv;
  std::uint64_t stamped = 0;  // stamped frames reflected by the samples
  std::uint64_t samples = 0;  // samples that reflect at least one stamped frame
  std::uint64_t other = 0;    // initial samples, NMT changes
  std::vector<std::int64_t> latencies;
  std::vector<std::int64_t> last_latencies;  // TPDO2's alone: the last TPDO of a saw's cycle
  Clock::time_point last_sample{};
  bool have_diag = false;
  msg::Diagnostics diag;
  Clock::time_point diag_at{};
};

}  // namespace

int main(int argc, char** argv) {
  bench::Program program{"bench-status-sub", "times and counts the saw status samples of the bench line"};
  auto& cli = program.cli;
  std::uint64_t expect = 10000;
  std::uint64_t warmup = 0;
  double idle_s = 3;
  double timeout_s = 600;
  bool diagnostics = false;
  std::string name = "bench-sub";
  program.add_buses();
  program.add_devices("saws per bus");
  program.add_domain();
  cli.add_option("--expect", expect, "stamped samples to receive, warm-up included")->capture_default_str();
  cli.add_option("--warmup", warmup, "first samples left out of the latency figures")->capture_default_str();
  cli.add_option("--idle", idle_s, "stop after this long without a sample, once samples flowed")->capture_default_str();
  cli.add_option("--timeout", timeout_s, "stop after this long in any case")->capture_default_str();
  cli.add_flag("--diagnostics", diagnostics, "also report the bridge's own counters (rt/bench/bridge/diagnostics)");
  program.add_out();
  program.add_ready("every status topic has a matched writer");
  cli.add_option("--name", name, "participant name")->capture_default_str();
  program.add_security();
  if (auto rc = program.parse(argc, argv)) return *rc;
  const int buses = program.buses;
  const int devices = program.devices;

  // Declared before the participant, so they outlive every listener call.
  Tally tally;
  tally.latencies.reserve(expect);
  std::vector<bench::StampDecoder> decoders(static_cast<std::size_t>(buses * devices));
  auto dds = lb::ddsl::Participant::create(bench::participant_options(program, name));
  if (!dds) return program.fail(dds.error().message);
  std::vector<std::string> topics;
  for (int b = 0; b < buses; ++b) {
    for (int d = 0; d < devices; ++d) {
      const std::size_t index = topics.size();
      topics.push_back(lb::ddsl::topic_name(bench::kLine, bench::device_name(b, d), "status"));
      // One reader per device: its listener calls are serialised, so its decoder needs no lock.
      auto sub = (*dds)->subscribe<msg::SawStatusPubSubType>(
          topics.back(), lb::ddsl::QosKind::state,
          [&tally, &decoders, index, warmup](const msg::SawStatus& s, const lb::ddsl::fdds::SampleInfo&) {
            const auto now = bench::realtime_ns();
            const auto hits = decoders[index].next(s);
            {
              std::lock_guard lock(tally.m);
              if (hits.n == 0) {
                ++tally.other;
                return;
              }
              ++tally.samples;
              for (int i = 0; i < hits.n; ++i) {
                const auto& hit = hits.hit[static_cast<std::size_t>(i)];
                if (tally.stamped++ < warmup) continue;
                tally.latencies.push_back(bench::elapsed_since(hit.stamp, now));
                if (hit.tpdo2) tally.last_latencies.push_back(tally.latencies.back());
              }
              tally.last_sample = Clock::now();
            }
            // No notify: the main thread polls every 50 ms, and a wake-up per sample would cost
            // this process as much as receiving the sample.
          },
          100);  // deeper than keep-last 1, so a burst is not thinned out on the reading side
      if (!sub) return program.fail(sub.error().message);
    }
  }
  if (diagnostics) {
    auto sub = (*dds)->subscribe<msg::DiagnosticsPubSubType>(
        lb::ddsl::topic_name(bench::kLine, "bridge", "diagnostics"), lb::ddsl::QosKind::state,
        [&tally](const msg::Diagnostics& d, const lb::ddsl::fdds::SampleInfo&) {
          std::lock_guard lock(tally.m);
          tally.diag = d;
          tally.have_diag = true;
          tally.diag_at = Clock::now();
          tally.cv.notify_all();
        });
    if (!sub) return program.fail(sub.error().message);
  }

  const auto deadline = Clock::now() +
                        std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
  for (bool matched = false; !matched;) {
    matched = true;
    for (const auto& t : topics) matched = matched && (*dds)->matched_writers(t) > 0;
    if (Clock::now() > deadline) {
      return program.fail("not every status topic has a writer");
    }
    if (!matched) std::this_thread::sleep_for(10ms);
  }
  program.ready();

  const auto idle = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(idle_s));
  Clock::time_point finished;
  {
    std::unique_lock lock(tally.m);
    while (tally.stamped < expect && Clock::now() < deadline) {
      if (tally.stamped > 0 && Clock::now() - tally.last_sample > idle) break;
      tally.cv.wait_for(lock, 50ms);
    }
    finished = Clock::now();
    // Counters from a diagnostics snapshot taken after the last sample (published once a second).
    if (diagnostics) {
      tally.cv.wait_until(lock, finished + 3s, [&] { return tally.have_diag && tally.diag_at > finished + 1100ms; });
    }
  }

  std::lock_guard lock(tally.m);
  std::string report = fmt::format("sub_expected={}\nsub_stamped={}\nsub_samples={}\nsub_other={}\nsub_missing={}\n",
                                   expect, tally.stamped, tally.samples, tally.other,
                                   expect > tally.stamped ? expect - tally.stamped : 0);
  if (diagnostics && tally.have_diag) {
    std::uint64_t frames_in = 0, error_frames = 0, pdos = 0, length_errors = 0;
    for (const auto& b : tally.diag.buses()) {
      frames_in += b.frames_in();
      error_frames += b.error_frames();
    }
    for (const auto& n : tally.diag.nodes()) {
      pdos += n.pdos_received();
      length_errors += n.pdo_length_errors();
    }
    report += fmt::format(
        "bridge_frames_in={}\nbridge_error_frames={}\nbridge_pdos_received={}\nbridge_pdo_length_errors={}\n",
        frames_in, error_frames, pdos, length_errors);
  }
  report += bench::format_summary("sub", bench::summarize(tally.latencies));
  report += bench::format_summary("sub_last", bench::summarize(tally.last_latencies));
  std::fputs(report.c_str(), stdout);
  std::fflush(stdout);
  program.save_latencies(tally.latencies);
  return tally.stamped == expect ? 0 : 3;
}
