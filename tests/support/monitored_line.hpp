#pragma once
// A line that a monitor-role bridge watches: the simulator plays the devices (and, when a test
// starts it, the line controller) as the master of bus `m`; the real bridge sits on the same bus
// with role: monitor and must only listen. This test is a passive member of the bus (BusSpy).
// The spy is the bus's first member, before either process.

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <fstream>
#include <set>
#include <string>

#include "dds/participant.hpp"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/spy_waits.hpp"

namespace lb::test {

class MonitoredLine {
 public:
  // line: its name (and the files' prefix); devices: the devices: section, every device on bus m.
  MonitoredLine(const std::string& line, std::uint32_t domain, const std::string& devices)
      : tag_(std::to_string(::getpid())),
        dir_(::testing::TempDir()),
        bus_("virtual:" + line + "-" + tag_),
        line_config_(
            write(dir_ + "/" + line + "_line_" + tag_ + ".yaml",
                  "line: " + line + "\nbuses:\n  - {name: m, interface: '" + bus_ + "', role: master}\n" + devices)),
        bridge_config_(write(dir_ + "/" + line + "_bridge_" + tag_ + ".yaml",
                             "line: " + line + "\ndds: {domain: " + std::to_string(domain) +
                                 "}\nbuses:\n  - {name: m, interface: '" + bus_ + "', role: monitor}\n" + devices)),
        spy_(bus_),
        devices_({LB_BIN_SIM, "--config", line_config_, "--role", "devices"},
                 dir_ + "/" + line + "_devices_" + tag_ + ".log"),
        bridge_({LB_BIN_BRIDGE, "--config", bridge_config_}, dir_ + "/" + line + "_bridge_" + tag_ + ".log") {}

  BusSpy& spy() { return spy_; }
  ChildProcess& bridge() { return bridge_; }
  // The simulator's line file: a test starts the line controller (--role controller) with it.
  const std::string& line_config() const { return line_config_; }
  std::string logs() const { return "--- bridge ---\n" + bridge_.log() + "--- devices ---\n" + devices_.log(); }

  // The identifiers of every frame the spy saw since it was last cleared, taken once `beats` more
  // heartbeats of `node` came (the marker of the negative check: the bus went on that long, and
  // whatever was sent before the last of them is in).
  std::set<std::uint32_t> ids_after_heartbeats(std::uint8_t node, std::size_t beats) {
    EXPECT_TRUE(wait_frames_after(spy_, 0x700u + node, bus_now_ns(), beats, std::chrono::seconds(30)))
        << "fewer than " << beats << " heartbeats of node " << int{node} << "\n"
        << logs();
    std::set<std::uint32_t> ids;
    for (const auto& f : spy_.frames()) ids.insert(f.id);
    return ids;
  }

 private:
  static std::string write(const std::string& path, const std::string& text) {
    std::ofstream(path) << text;
    return path;
  }

  std::string tag_, dir_, bus_, line_config_, bridge_config_;
  BusSpy spy_;
  ChildProcess devices_, bridge_;
};

// A request to a service of the monitoring bridge (`path`: line-wide or the device's own): refused,
// with the monitor role as the reason. The client goes before the participant it lives in.
template <class Client>
void expect_refused_by_monitor(ddsl::Participant& dds, const std::string& path, const typename Client::Request& req) {
  auto client = Client::create(dds, path);
  ASSERT_TRUE(client) << client.error().message;
  auto r = (*client)->call(req, std::chrono::seconds(10));
  ASSERT_TRUE(r) << r.error().message;
  EXPECT_FALSE(r->success());
  EXPECT_NE(r->message().find("monitor role"), std::string::npos) << r->message();
}

}  // namespace lb::test
