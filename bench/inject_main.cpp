// bench-inject: plays D saws on each of N virtual buses, sending their TPDOs at a fixed frame rate
// per bus, each frame carrying its send time (saw_stamps.hpp). It opens the buses before anyone
// else, so the virtual-bus hubs run in this process, as the controller and wire do on a real bus:
// their cost is the harness's, not the bridge's.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "clock.hpp"
#include "program.hpp"
#include "saw_stamps.hpp"

namespace bench = lb::bench;
using namespace std::chrono_literals;

int main(int argc, char** argv) {
  bench::Program program{"bench-inject", "saw TPDOs with send stamps on N virtual buses"};
  program.add_buses();
  program.add_devices("saws per bus");
  program.add_load("frames per second on each bus", "frames per bus");
  program.add_prefix();
  program.add_ready("the buses are open");
  program.add_go("start sending");
  program.add_stop("sending");
  bool sync = false;
  program.cli.add_flag("--sync", sync,
                       "a SYNC (080h) on each bus before every round of its saws' TPDO1 and TPDO2, as a master "
                       "sends it: the cycle the bridge's status_publish per_cycle waits for (not counted in the rate)");
  if (auto rc = program.parse(argc, argv)) return *rc;
  const int buses = program.buses;
  const int devices = program.devices;
  const double rate = program.rate;
  const std::uint64_t count = program.count;

  std::vector<std::unique_ptr<lb::can::Bus>> bus;
  for (int b = 0; b < buses; ++b) {
    auto opened = lb::can::open_bus(bench::bus_uri(program.prefix, b));
    if (!opened) return program.fail(opened.error().message);
    bus.push_back(std::move(*opened));
  }
  program.ready();
  if (!program.go()) return 1;

  // Frames interleave across buses and, on each bus, cycle through its saws: every saw sends
  // TPDO1 and TPDO2 in turn, as at every SYNC.
  std::vector<std::uint32_t> k(static_cast<std::size_t>(buses * devices), 0);
  std::vector<std::uint64_t> dropped(static_cast<std::size_t>(buses), 0);
  std::uint64_t sent = 0;
  std::uint64_t syncs = 0;
  const auto cycle = static_cast<std::uint64_t>(2 * devices);  // frames per bus between two SYNCs
  lb::can::CanFrame sync_frame;
  sync_frame.id = 0x080;
  bench::Pacer pacer(rate * buses);
  pacer.start();
  const std::uint64_t total = count * static_cast<std::uint64_t>(buses);
  for (std::uint64_t i = 0; i < total; ++i) {
    pacer.wait(i);
    const auto b = static_cast<int>(i % static_cast<std::uint64_t>(buses));
    const auto d = static_cast<int>((i / static_cast<std::uint64_t>(buses)) % static_cast<std::uint64_t>(devices));
    auto& kd = k[static_cast<std::size_t>(b * devices + d)];
    if (sync && (i / static_cast<std::uint64_t>(buses)) % cycle == 0 &&
        bus[static_cast<std::size_t>(b)]->send(sync_frame)) {
      ++syncs;
    }
    const auto frame = bench::saw_tpdo(bench::node_id(d), ++kd, bench::stamp32(bench::realtime_ns()));
    if (bus[static_cast<std::size_t>(b)]->send(frame)) {
      ++sent;
    } else {
      ++dropped[static_cast<std::size_t>(b)];
    }
  }
  const double elapsed = pacer.elapsed_s();
  std::uint64_t dropped_total = 0;
  for (auto n : dropped) dropped_total += n;
  std::fputs(fmt::format("inject_frames_sent={}\ninject_syncs_sent={}\ninject_tx_dropped={}\ninject_elapsed_s={:.3f}\n"
                         "inject_rate_per_bus={:.0f}\ninject_max_lag_ms={:.2f}\n",
                         sent, syncs, dropped_total, elapsed, static_cast<double>(sent) / elapsed / buses,
                         static_cast<double>(pacer.max_lag_ns()) / 1e6)
                 .c_str(),
             stdout);
  std::fflush(stdout);

  program.linger();  // the hubs live in this process: leaving now would lose the frames they still forward
  return 0;
}
