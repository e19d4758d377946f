// bench-inject: plays D saws on each of N virtual buses, sending their TPDOs at a fixed frame rate
// per bus, each frame carrying its send time (saw_stamps.hpp). It opens the buses before anyone
// else, so the virtual-bus hubs run in this process, as the controller and wire do on a real bus:
// their cost is the harness's, not the bridge's.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <memory>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "clock.hpp"
#include "names.hpp"
#include "rendezvous.hpp"
#include "saw_stamps.hpp"

namespace bench = lb::bench;
using namespace std::chrono_literals;

int main(int argc, char** argv) {
  CLI::App cli{"bench-inject: saw TPDOs with send stamps on N virtual buses"};
  int buses = 1;
  int devices = 30;
  double rate = 3000;
  std::uint64_t count = 10000;
  std::string prefix = "bench";
  std::string ready_file, go_file, stop_file;
  double linger_s = 2;
  cli.add_option("--buses", buses)->check(CLI::Range(1, 64))->capture_default_str();
  cli.add_option("--devices", devices, "saws per bus")->check(CLI::Range(1, bench::kMaxDevicesPerBus))->capture_default_str();
  cli.add_option("--rate", rate, "frames per second on each bus")->check(CLI::PositiveNumber)->capture_default_str();
  cli.add_option("--count", count, "frames per bus")->capture_default_str();
  cli.add_option("--prefix", prefix, "virtual bus names: <prefix>-<i>")->capture_default_str();
  cli.add_option("--ready", ready_file, "created once the buses are open");
  cli.add_option("--go", go_file, "start sending once this file exists");
  cli.add_option("--stop", stop_file, "after sending, keep the hubs up until this file exists (or --linger)");
  cli.add_option("--linger", linger_s, "at most this long after sending, seconds")->capture_default_str();
  CLI11_PARSE(cli, argc, argv);

  std::vector<std::unique_ptr<lb::can::Bus>> bus;
  for (int b = 0; b < buses; ++b) {
    auto opened = lb::can::open_bus(bench::bus_uri(prefix, b));
    if (!opened) {
      std::fprintf(stderr, "bench-inject: %s\n", opened.error().message.c_str());
      return 1;
    }
    bus.push_back(std::move(*opened));
  }
  bench::signal_file(ready_file);
  if (!bench::await_file(go_file, 300s)) {
    std::fprintf(stderr, "bench-inject: no go within 300 s\n");
    return 1;
  }

  // Frames interleave across buses and, on each bus, cycle through its saws: every saw sends
  // TPDO1 and TPDO2 in turn, as at every SYNC.
  std::vector<std::uint32_t> k(static_cast<std::size_t>(buses * devices), 0);
  std::vector<std::uint64_t> dropped(static_cast<std::size_t>(buses), 0);
  std::uint64_t sent = 0;
  bench::Pacer pacer(rate * buses);
  pacer.start();
  const std::uint64_t total = count * static_cast<std::uint64_t>(buses);
  for (std::uint64_t i = 0; i < total; ++i) {
    pacer.wait(i);
    const auto b = static_cast<int>(i % static_cast<std::uint64_t>(buses));
    const auto d = static_cast<int>((i / static_cast<std::uint64_t>(buses)) % static_cast<std::uint64_t>(devices));
    auto& kd = k[static_cast<std::size_t>(b * devices + d)];
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
  std::fputs(fmt::format("inject_frames_sent={}\ninject_tx_dropped={}\ninject_elapsed_s={:.3f}\n"
                         "inject_rate_per_bus={:.0f}\ninject_max_lag_ms={:.2f}\n",
                         sent, dropped_total, elapsed, static_cast<double>(sent) / elapsed / buses,
                         static_cast<double>(pacer.max_lag_ns()) / 1e6)
                 .c_str(),
             stdout);
  std::fflush(stdout);

  // The hubs live in this process: leaving now would lose the frames they still forward.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(linger_s);
  while (!bench::file_exists(stop_file) && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(10ms);
  }
  return 0;
}
