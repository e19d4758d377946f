// bench-relay: the floor of DDS -> CAN. A bare Fast DDS reader of a saw's set values that puts
// each one on the bus as RPDO1 straight from the listener: the DDS hop and the bus hop in series
// with nothing in between, measured by bench-setpoint exactly as the bridge is.
// --handoff sends through the bridge's own BusLoop instead (post() to the loop thread, which
// sends): the floor plus the one thread hand-over the bridge's design puts on this path, so the
// bridge's overhead can be split into that hand-over and everything else.
#include <CLI/CLI.hpp>
#include <signal.h>

#include <cmath>
#include <cstdio>
#include <mutex>

#include "can/bus.hpp"
#include "canopen/bus_loop.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/sawPubSubTypes.h"
#include "names.hpp"
#include "rendezvous.hpp"
#include "saw_stamps.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;

int main(int argc, char** argv) {
  CLI::App cli{"bench-relay: set values from DDS to CAN with nothing in between"};
  std::string prefix = "bench";
  int domain = 0;
  std::string ready_file;
  bool handoff = false;
  cli.add_option("--prefix", prefix)->capture_default_str();
  cli.add_flag("--handoff", handoff, "send from a BusLoop thread (post), as the bridge does");
  cli.add_option("--domain", domain)->capture_default_str();
  cli.add_option("--ready", ready_file, "created once subscribed");
  CLI11_PARSE(cli, argc, argv);

  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);  // before any thread starts: they inherit it

  auto bus = lb::can::open_bus(bench::bus_uri(prefix, 0));
  if (!bus) {
    std::fprintf(stderr, "bench-relay: %s\n", bus.error().message.c_str());
    return 1;
  }
  std::mutex bus_mutex;  // a Bus is used by one thread at a time
  std::unique_ptr<lb::canopen::BusLoop> loop;
  if (handoff) {
    loop = std::make_unique<lb::canopen::BusLoop>(std::move(*bus));
    loop->start();
  }
  auto dds = lb::ddsl::Participant::create({static_cast<std::uint32_t>(domain), true, "bench-relay"});
  if (!dds) {
    std::fprintf(stderr, "bench-relay: %s\n", dds.error().message.c_str());
    return 1;
  }
  const std::uint8_t node = bench::node_id(0);
  auto sub = (*dds)->subscribe<msg::SawSetpointPubSubType>(
      lb::ddsl::topic_name(bench::kLine, bench::device_name(0, 0), "setpoint"), lb::ddsl::QosKind::command,
      [&](const msg::SawSetpoint& sp, const lb::ddsl::fdds::SampleInfo&) {
        lb::can::CanFrame f;
        f.id = 0x200 + node;
        f.len = 8;
        bench::put_le(&f.data[0], sp.saw_program_on() ? 1U : 0U, 2);
        bench::put_le(&f.data[2], static_cast<std::uint32_t>(std::llround(sp.sync_speed_percent() * 100)), 2);
        bench::put_le(&f.data[4], static_cast<std::uint32_t>(std::llround(sp.product_length_m() * 10000)), 4);
        if (loop) {
          loop->post([&loop, f] { (void)loop->send(f); });
          return;
        }
        std::lock_guard lock(bus_mutex);
        (void)(*bus)->send(f);
      });
  if (!sub) {
    std::fprintf(stderr, "bench-relay: %s\n", sub.error().message.c_str());
    return 1;
  }
  bench::signal_file(ready_file);
  int sig = 0;
  sigwait(&stop_signals, &sig);
  dds->reset();  // no listener call after this, before the loop and the bus go
  if (loop) loop->stop();
  return 0;
}
