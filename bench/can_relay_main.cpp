// bench-can-relay: a bare CAN -> DDS relay, the serial floor of the bridge's CAN -> DDS path. One
// thread waits on the bus as the bridge's bus loop does, and writes each stamped saw TPDO as that
// saw's status sample with a bare Fast DDS writer (the bridge's type and QoS), filled by hand
// from the frame's bytes instead of through a profile. Unlike the two separate floor hops it runs
// the same three processes at the same time as the bridge's path does, so the comparison also
// holds for the latency tail on a machine where those processes compete for the cores.
#include <poll.h>

#include "can/bus.hpp"
#include "dds/participant.hpp"
#include "program.hpp"
#include "saw_stamps.hpp"
#include "status_writers.hpp"
#include "stop_signals.hpp"

namespace bench = lb::bench;

int main(int argc, char** argv) {
  bench::Program program{"bench-can-relay",
                         "saw TPDOs from a virtual bus to DDS status samples with nothing in between"};
  program.add_prefix();
  program.add_devices("saws on bus 0");
  program.add_domain();
  program.add_ready("the bus is open and the writers exist");
  if (auto rc = program.parse(argc, argv)) return *rc;
  const int devices = program.devices;
  bench::StopSignals stop;  // before any thread starts

  auto bus = lb::can::open_bus(bench::bus_uri(program.prefix, 0));
  if (!bus) return program.fail(bus.error().message);
  auto dds = lb::ddsl::Participant::create({static_cast<std::uint32_t>(program.domain), true, program.name()});
  if (!dds) return program.fail(dds.error().message);
  auto status = bench::status_writers(**dds, devices);
  if (!status) return program.fail(status.error().message);
  auto& [writers, samples] = *status;
  program.ready();

  for (;;) {
    pollfd p{(*bus)->fd(), POLLIN, 0};
    if (::poll(&p, 1, 100) > 0) {
      for (;;) {
        auto frame = (*bus)->receive();
        if (!frame || !frame->has_value()) break;
        const auto& f = **frame;
        if (f.error || f.extended || f.rtr) continue;
        const bool tpdo1 = f.id > bench::kTpdo1Base && f.id < bench::kTpdo1Base + 0x80 && f.len == 6;
        const bool tpdo2 = f.id > bench::kTpdo2Base && f.id < bench::kTpdo2Base + 0x80 && f.len == 8;
        if (!tpdo1 && !tpdo2) continue;
        const int d = static_cast<int>(f.id & 0x7F) - bench::kFirstNodeId;
        if (d < 0 || d >= devices) continue;
        auto& s = samples[static_cast<std::size_t>(d)];
        if (tpdo1) {
          bench::apply_tpdo(s, 1, bench::get_le32(&f.data[2]));
        } else {
          bench::apply_tpdo(s, bench::get_le32(&f.data[4]), bench::get_le32(&f.data[0]));
        }
        const auto st = lb::ddsl::to_stamp(f.timestamp_ns);
        s.stamp().sec(st.sec);
        s.stamp().nanosec(st.nanosec);
        writers[static_cast<std::size_t>(d)].write(s);
      }
    }
    if (stop.requested()) break;
  }
  dds->reset();
  return 0;
}
