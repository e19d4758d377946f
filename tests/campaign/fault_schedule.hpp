#pragma once
// The fault campaign's schedule: every fault it injects, drawn from the seed alone, so that a run
// is replayed by giving its seed again (the same faults, targets, variants and moments; what the
// processes make of them may differ by a few milliseconds). Faults come in rounds: each round is
// every kind once, in an order drawn from the seed, so a short run (CI's) meets every kind too.
// Two faults never overlap on one target (a device, the bridge, a bus, a client): each waits until
// the target's previous fault is over and it had time to recover.
//
// Bus-off is not among them: the virtual bus cannot emulate it (a member may send an error frame,
// but the bus goes on carrying every frame, so a "bus-off" would be a lie the judge cannot read).

#include <algorithm>
#include <cstdint>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "can/can_frame.hpp"

namespace lb::test::campaign {

enum class FaultKind {
  power_cycle,         // a device's simulator SIGKILLed, started again after a random delay
  device_stall,        // a device's simulator SIGSTOPped, SIGCONTed after a random delay
  kill_bus_process,    // kill -9 of the bridge's bus process, started again after a random delay
  kill_dds_process,    // kill -9 of the bridge's DDS process (its bus process starts another)
  bridge_restart,      // SIGTERM to the bridge, started again at once
  spoofed_heartbeats,  // frames on a device's heartbeat identifier it did not send
  spoofed_syncs,       // SYNCs from another "master"
  spoofed_sdo,         // an SDO download to a device's 1017h (producer heartbeat time)
  stalled_client,      // a DDS client of the line SIGSTOPped, SIGCONTed after a random delay
};
inline constexpr FaultKind kAllFaults[] = {
    FaultKind::power_cycle,      FaultKind::device_stall,   FaultKind::kill_bus_process,
    FaultKind::kill_dds_process, FaultKind::bridge_restart, FaultKind::spoofed_heartbeats,
    FaultKind::spoofed_syncs,    FaultKind::spoofed_sdo,    FaultKind::stalled_client,
};

inline const char* name(FaultKind k) {
  switch (k) {
    case FaultKind::power_cycle: return "device power cycle (SIGKILL, started again)";
    case FaultKind::device_stall: return "device stalled (SIGSTOP, SIGCONT)";
    case FaultKind::kill_bus_process: return "kill -9 of the bus process (started again)";
    case FaultKind::kill_dds_process: return "kill -9 of the DDS process";
    case FaultKind::bridge_restart: return "bridge restart (SIGTERM, started again)";
    case FaultKind::spoofed_heartbeats: return "spoofed heartbeats / boot-ups";
    case FaultKind::spoofed_syncs: return "spoofed SYNCs";
    case FaultKind::spoofed_sdo: return "spoofed SDO write (1017h)";
    case FaultKind::stalled_client: return "stalled DDS client (SIGSTOP, SIGCONT)";
  }
  return "?";
}

// One step of a fault at its moment (ms from the campaign's start): a process acted on, or a
// spoofed frame sent (`frame`).
struct FaultStep {
  std::int64_t at_ms = 0;
  std::size_t fault = 0;  // index into FaultSchedule::faults
  int step = 0;           // 0: the fault begins; 1: it ends (the process back); spoofed: the frame's number
  std::optional<lb::can::CanFrame> frame;
};

struct Fault {
  FaultKind kind;
  std::int64_t at_ms = 0;
  std::size_t target = 0;  // a device's or client's index, or a bus's (spoofed SYNCs); the bridge: 0
  std::int64_t lasts_ms = 0;
  std::string variant;  // what exactly, for the log and the count
};

// What the schedule needs to know of the line.
struct ScheduleTargets {
  struct Device {
    std::string name;
    int node;
    std::size_t bus;  // index into buses
  };
  std::vector<Device> devices;
  std::vector<std::string> buses;
  std::size_t clients = 0;
};

struct FaultSchedule {
  std::vector<Fault> faults;
  std::vector<FaultStep> steps;  // in the order of their moments

  // duration_ms: the campaign's; faults begin after first_ms and are over (recovered) by
  // duration_ms - quiet_ms; mean_gap_ms: the mean time between two faults' beginnings.
  static FaultSchedule draw(std::uint64_t seed, const ScheduleTargets& line, std::int64_t duration_ms,
                            std::int64_t mean_gap_ms, std::int64_t first_ms = 8'000, std::int64_t quiet_ms = 20'000) {
    // std::mt19937_64 is the same sequence everywhere; the <random> distributions are not, so the
    // draws below take its numbers directly.
    std::mt19937_64 rng(seed);
    const auto draw_in = [&rng](std::int64_t lo, std::int64_t hi) {
      return lo + static_cast<std::int64_t>(rng() % static_cast<std::uint64_t>(hi - lo + 1));
    };
    FaultSchedule s;
    std::map<std::string, std::int64_t> free_at;  // a target's next fault may begin then
    const std::int64_t end = duration_ms - quiet_ms;
    std::int64_t t = first_ms;
    while (t < end) {
      std::vector<FaultKind> round(std::begin(kAllFaults), std::end(kAllFaults));
      for (std::size_t i = round.size() - 1; i > 0; --i) {
        std::swap(round[i], round[static_cast<std::size_t>(draw_in(0, static_cast<std::int64_t>(i)))]);
      }
      for (const auto kind : round) {
        if (t >= end) break;
        Fault f{kind, 0, 0, 0, {}};
        std::string key = "bridge";
        std::int64_t recover_ms = 3'000;
        const auto device = [&] {
          f.target = static_cast<std::size_t>(draw_in(0, static_cast<std::int64_t>(line.devices.size()) - 1));
          key = "device " + line.devices[f.target].name;
        };
        switch (kind) {
          case FaultKind::power_cycle:
            device();
            f.lasts_ms = draw_in(200, 4'000);
            f.variant = fmt::format("{} off for {} ms", line.devices[f.target].name, f.lasts_ms);
            break;
          case FaultKind::device_stall:
            device();
            f.lasts_ms = draw_in(200, 2'500);
            f.variant = fmt::format("{} stalled for {} ms", line.devices[f.target].name, f.lasts_ms);
            break;
          case FaultKind::kill_bus_process:
            f.lasts_ms = draw_in(100, 3'000);
            f.variant = fmt::format("started again after {} ms", f.lasts_ms);
            recover_ms = 5'000;
            break;
          case FaultKind::kill_dds_process: f.variant = "its bus process starts another"; break;
          case FaultKind::bridge_restart:
            f.variant = "SIGTERM, then started";
            recover_ms = 5'000;
            break;
          case FaultKind::spoofed_heartbeats: {
            device();
            static constexpr const char* kVariants[] = {"10 pairs of a boot-up and a pre-operational heartbeat",
                                                        "one stopped heartbeat", "5 boot-ups"};
            f.variant = fmt::format("{}: {}", line.devices[f.target].name, kVariants[draw_in(0, 2)]);
            break;
          }
          case FaultKind::spoofed_syncs:
            f.target = static_cast<std::size_t>(draw_in(0, static_cast<std::int64_t>(line.buses.size()) - 1));
            key = "bus " + line.buses[f.target];
            f.variant = "on " + line.buses[f.target] + ": 10 within 225 ms, then one every 4.5 s for 18 s";
            recover_ms = 1'000;
            break;
          case FaultKind::spoofed_sdo: {
            device();
            static constexpr const char* kVariants[] = {"1017h := 0 (no more heartbeats)",
                                                        "1017h := 5000 ms (slower than its heartbeat timeout)"};
            f.variant = fmt::format("{}: {}", line.devices[f.target].name, kVariants[draw_in(0, 1)]);
            break;
          }
          case FaultKind::stalled_client:
            f.target = static_cast<std::size_t>(draw_in(0, static_cast<std::int64_t>(line.clients) - 1));
            key = "client " + std::to_string(f.target);
            f.lasts_ms = draw_in(2'000, 20'000);
            f.variant = fmt::format("client {} stalled for {} ms", f.target, f.lasts_ms);
            recover_ms = 1'000;
            break;
        }
        f.at_ms = std::max(t, free_at[key]);
        auto steps = steps_of(f, s.faults.size(), line);
        const auto over = steps.back().at_ms;
        if (over + recover_ms > end) {
          t += draw_in(mean_gap_ms / 2, mean_gap_ms * 3 / 2);
          continue;
        }
        free_at[key] = over + recover_ms;
        s.faults.push_back(std::move(f));
        for (auto& step : steps) s.steps.push_back(std::move(step));
        t += draw_in(mean_gap_ms / 2, mean_gap_ms * 3 / 2);
      }
    }
    std::stable_sort(s.steps.begin(), s.steps.end(), [](const auto& a, const auto& b) { return a.at_ms < b.at_ms; });
    return s;
  }

 private:
  static std::vector<FaultStep> steps_of(const Fault& f, std::size_t index, const ScheduleTargets& line) {
    std::vector<FaultStep> out;
    const auto at = [&](std::int64_t ms, int step, std::optional<lb::can::CanFrame> frame = std::nullopt) {
      out.push_back({f.at_ms + ms, index, step, std::move(frame)});
    };
    switch (f.kind) {
      case FaultKind::power_cycle:
      case FaultKind::device_stall:
      case FaultKind::kill_bus_process:
      case FaultKind::stalled_client:
        at(0, 0);
        at(f.lasts_ms, 1);
        break;
      case FaultKind::kill_dds_process:
      case FaultKind::bridge_restart: at(0, 0); break;
      case FaultKind::spoofed_heartbeats: {
        const auto id = 0x700u + static_cast<std::uint32_t>(line.devices[f.target].node);
        if (f.variant.find("pairs") != std::string::npos) {
          for (int i = 0; i < 10; ++i) {
            at(100 * i, 2 * i, lb::can::make_frame(id, {0x00}));
            at(100 * i + 50, 2 * i + 1, lb::can::make_frame(id, {0x7F}));
          }
        } else if (f.variant.find("stopped") != std::string::npos) {
          at(0, 0, lb::can::make_frame(id, {0x04}));
        } else {
          for (int i = 0; i < 5; ++i) at(200 * i, i, lb::can::make_frame(id, {0x00}));
        }
        break;
      }
      case FaultKind::spoofed_syncs:
        for (int i = 0; i < 10; ++i) at(25 * i, i, lb::can::make_frame(0x080, {}));
        for (int i = 1; i <= 4; ++i) at(225 + 4'500 * i, 9 + i, lb::can::make_frame(0x080, {}));
        break;
      case FaultKind::spoofed_sdo: {
        const auto id = 0x600u + static_cast<std::uint32_t>(line.devices[f.target].node);
        // CiA 301 expedited download of 2 bytes (2Bh) to 1017h sub 0: the producer heartbeat time.
        const std::uint8_t lo = f.variant.find(":= 0 ") != std::string::npos ? 0x00 : 0x88;
        const std::uint8_t hi = f.variant.find(":= 0 ") != std::string::npos ? 0x00 : 0x13;  // 1388h = 5000 ms
        at(0, 0, lb::can::make_frame(id, {0x2B, 0x17, 0x10, 0x00, lo, hi, 0x00, 0x00}));
        break;
      }
    }
    return out;
  }
};

}  // namespace lb::test::campaign
