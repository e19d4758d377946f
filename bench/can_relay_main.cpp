// bench-can-relay: a bare CAN -> DDS relay, the serial floor of the bridge's CAN -> DDS path. One
// thread waits on the bus as the bridge's bus loop does, and writes each stamped saw TPDO as that
// saw's status sample with a bare Fast DDS writer (the bridge's type and QoS), filled by hand
// from the frame's bytes instead of through a profile. Unlike the two separate floor hops it runs
// the same three processes at the same time as the bridge's path does, so the comparison also
// holds for the latency tail on a machine where those processes compete for the cores.
#include <CLI/CLI.hpp>
#include <poll.h>
#include <signal.h>

#include <cstdio>
#include <vector>

#include "can/bus.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/sawPubSubTypes.h"
#include "names.hpp"
#include "rendezvous.hpp"
#include "saw_stamps.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;

int main(int argc, char** argv) {
  CLI::App cli{"bench-can-relay: saw TPDOs from a virtual bus to DDS status samples with nothing in between"};
  std::string prefix = "bench";
  int devices = 30;
  int domain = 0;
  std::string ready_file;
  cli.add_option("--prefix", prefix)->capture_default_str();
  cli.add_option("--devices", devices, "saws (of bus 0)")->check(CLI::Range(1, bench::kMaxDevicesPerBus))->capture_default_str();
  cli.add_option("--domain", domain)->capture_default_str();
  cli.add_option("--ready", ready_file, "created once the bus is open and the writers exist");
  CLI11_PARSE(cli, argc, argv);

  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGINT);
  sigaddset(&stop_signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);  // before any thread starts: they inherit it

  auto bus = lb::can::open_bus(bench::bus_uri(prefix, 0));
  if (!bus) {
    std::fprintf(stderr, "bench-can-relay: %s\n", bus.error().message.c_str());
    return 1;
  }
  auto dds = lb::ddsl::Participant::create({static_cast<std::uint32_t>(domain), true, "bench-can-relay"});
  if (!dds) {
    std::fprintf(stderr, "bench-can-relay: %s\n", dds.error().message.c_str());
    return 1;
  }
  std::vector<lb::ddsl::Writer<msg::SawStatusPubSubType>> writers;
  std::vector<msg::SawStatus> samples(static_cast<std::size_t>(devices));
  for (int d = 0; d < devices; ++d) {
    auto w = (*dds)->writer<msg::SawStatusPubSubType>(lb::ddsl::topic_name(bench::kLine, bench::device_name(0, d), "status"),
                                                      lb::ddsl::QosKind::state);
    if (!w) {
      std::fprintf(stderr, "bench-can-relay: %s\n", w.error().message.c_str());
      return 1;
    }
    writers.push_back(*w);
    writers.back().write(samples[static_cast<std::size_t>(d)]);  // as the bridge: the device exists before its data
  }
  bench::signal_file(ready_file);

  const timespec no_wait{};
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
    if (sigtimedwait(&stop_signals, nullptr, &no_wait) > 0) break;
  }
  dds->reset();
  return 0;
}
