// bench-relay: the floor of DDS -> CAN. A bare Fast DDS reader of a saw's set values that puts
// each one on the bus as RPDO1 straight from the listener: the DDS hop and the bus hop in series
// with nothing in between, measured by bench-setpoint exactly as the bridge is.
// --handoff sends through the bridge's own BusLoop instead (post() to the loop thread, which
// sends): the floor plus the one thread hand-over the bridge's design puts on this path, so the
// bridge's overhead can be split into that hand-over and everything else.
#include <cmath>
#include <mutex>

#include "can/bus.hpp"
#include "canopen/bus_loop.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/sawPubSubTypes.h"
#include "program.hpp"
#include "saw_stamps.hpp"
#include "stop_signals.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;

int main(int argc, char** argv) {
  bench::Program program{"bench-relay", "set values from DDS to CAN with nothing in between"};
  auto& cli = program.cli;
  bool handoff = false;
  program.add_prefix();
  cli.add_flag("--handoff", handoff, "send from a BusLoop thread (post), as the bridge does");
  program.add_domain();
  program.add_ready("subscribed");
  if (auto rc = program.parse(argc, argv)) return *rc;
  bench::StopSignals stop;  // before any thread starts

  auto bus = lb::can::open_bus(bench::bus_uri(program.prefix, 0));
  if (!bus) return program.fail(bus.error().message);
  std::mutex bus_mutex;  // a Bus is used by one thread at a time
  std::unique_ptr<lb::canopen::BusLoop> loop;
  if (handoff) {
    loop = std::make_unique<lb::canopen::BusLoop>(std::move(*bus));
    loop->start();
  }
  auto dds = lb::ddsl::Participant::create({static_cast<std::uint32_t>(program.domain), true, program.name()});
  if (!dds) return program.fail(dds.error().message);
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
  if (!sub) return program.fail(sub.error().message);
  program.ready();
  stop.wait();
  dds->reset();  // no listener call after this, before the loop and the bus go
  if (loop) loop->stop();
  return 0;
}
