#include "app/bus_watch.hpp"

#include <fmt/format.h>
#include <poll.h>
#include <sys/signalfd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>

#include "app/arguments.hpp"
#include "app/stdout_gone.hpp"
#include "can/bus.hpp"
#include "can/candump_log.hpp"
#include "can/unique_fd.hpp"

namespace lb::app {
namespace {

std::string nmt_state_text(std::uint8_t s) {
  switch (s & 0x7F) {
    case 0x00: return "boot-up";
    case 0x04: return "stopped";
    case 0x05: return "operational";
    case 0x7F: return "pre-operational";
    default: return fmt::format("state {:02X}h", s);
  }
}

std::string nmt_command_text(std::uint8_t c) {
  switch (c) {
    case 0x01: return "start";
    case 0x02: return "stop";
    case 0x80: return "enter pre-operational";
    case 0x81: return "reset node";
    case 0x82: return "reset communication";
    default: return fmt::format("command {:02X}h", c);
  }
}

}  // namespace

std::string describe_frame(const can::CanFrame& f) {
  if (f.error) return "error frame";
  if (f.extended) return "29-bit identifier";
  const std::uint32_t function = f.id & 0x780;
  const std::uint32_t node = f.id & 0x7F;
  const std::string rtr = f.rtr ? " (remote request)" : "";
  if (f.id == 0x000) {
    if (f.len < 2) return "NMT (short)";
    return "NMT " + nmt_command_text(f.data[0]) + (f.data[1] == 0 ? " all nodes" : fmt::format(" node {}", f.data[1]));
  }
  if (f.id == 0x080) return "SYNC" + (f.len == 1 ? fmt::format(" counter {}", f.data[0]) : std::string());
  if (f.id == 0x100) return "TIME";
  if (node == 0) return fmt::format("COB-ID {:03X}h", f.id) + rtr;
  switch (function) {
    case 0x080:
      return fmt::format("EMCY node {}", node) +
             (f.len >= 2 ? fmt::format(" code {:02X}{:02X}h", f.data[1], f.data[0]) : "");
    case 0x180: return fmt::format("TPDO1 node {}", node) + rtr;
    case 0x200: return fmt::format("RPDO1 node {}", node);
    case 0x280: return fmt::format("TPDO2 node {}", node) + rtr;
    case 0x300: return fmt::format("RPDO2 node {}", node);
    case 0x380: return fmt::format("TPDO3 node {}", node) + rtr;
    case 0x400: return fmt::format("RPDO3 node {}", node);
    case 0x480: return fmt::format("TPDO4 node {}", node) + rtr;
    case 0x500: return fmt::format("RPDO4 node {}", node);
    case 0x580: return fmt::format("SDO answer from node {}", node);
    case 0x600: return fmt::format("SDO request to node {}", node);
    case 0x700:
      if (f.rtr) return fmt::format("node guarding request node {}", node);
      return fmt::format("heartbeat node {}", node) + (f.len >= 1 ? ": " + nmt_state_text(f.data[0]) : "");
    default: return fmt::format("COB-ID {:03X}h", f.id);
  }
}

int watch_bus(const profiles::LineConfig& line, const std::string& bus_name, const WatchOptions& o) {
  const auto* bus_cfg = line.bus(bus_name);
  if (bus_cfg == nullptr) {
    std::string known;
    for (const auto& b : line.buses) known += (known.empty() ? "" : ", ") + b.name;
    return fmt::print(stderr, "no bus '{}' on line {} (buses: {})\n", bus_name, line.line, known), kExitUsage;
  }
  if (bus_cfg->interface.rfind("log:", 0) == 0) {
    return fmt::print(stderr, "bus {} replays a recording ({}): read the file itself, it is in this format already\n",
                      bus_name, bus_cfg->interface),
           kExitUsage;
  }
  auto bus = can::open_bus(bus_cfg->interface, can::BusAccess::listen_only);
  if (!bus) return fmt::print(stderr, "bus {}: {}\n", bus_name, bus.error().message), kExitFailure;

  // The stop signals arrive on a descriptor polled with the bus (they are blocked in every thread).
  sigset_t stop;
  sigemptyset(&stop);
  sigaddset(&stop, SIGINT);
  sigaddset(&stop, SIGTERM);
  can::UniqueFd signals{::signalfd(-1, &stop, SFD_CLOEXEC)};
  const auto end = std::chrono::steady_clock::now() + duration_ms(o.duration_s);
  std::uint64_t seen = 0;
  for (;;) {
    int timeout_ms = -1;
    if (o.duration_s > 0) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(end - std::chrono::steady_clock::now());
      if (left.count() <= 0) return kExitOk;
      timeout_ms = static_cast<int>(std::min<long long>(left.count(), 1000));
    }
    pollfd fds[2] = {{(*bus)->fd(), POLLIN, 0}, {signals.get(), POLLIN, 0}};
    if (::poll(fds, 2, timeout_ms) < 0 && errno != EINTR) return kExitFailure;
    if ((fds[1].revents & POLLIN) != 0 || stdout_gone()) return kExitOk;
    for (;;) {
      auto frame = (*bus)->receive();
      if (!frame) return fmt::print(stderr, "bus {}: {}\n", bus_name, frame.error().message), kExitFailure;
      if (!*frame) break;
      std::string text = can::format_log_line(**frame, bus_name);
      if (!o.log_only) {
        text.pop_back();  // the newline
        text = fmt::format("{:<44} {}\n", text, describe_frame(**frame));
      }
      std::fputs(text.c_str(), stdout);
      if (o.count != 0 && ++seen >= o.count) return std::fflush(stdout), kExitOk;
    }
    if (std::fflush(stdout) != 0 || std::ferror(stdout)) return kExitOk;  // the reader of stdout is gone
  }
}

}  // namespace lb::app
