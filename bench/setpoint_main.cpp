// bench-setpoint: the application end of DDS -> CAN. Writes saw set values, each with a new
// product length, and times each from just before the write to the moment the RPDO1 frame that
// carries that length is received on the bus (this process is a member of the bus too, and opens
// it first, so it also runs the bus's hub). One set value at a time, with a short random pause in
// between, so no value waits behind another.
#include <fmt/format.h>
#include <poll.h>
#include <CLI/CLI.hpp>

#include <chrono>
#include <cstdio>
#include <random>
#include <thread>
#include <vector>

#include "can/bus.hpp"
#include "clock.hpp"
#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "latencies.hpp"
#include "msgs/sawPubSubTypes.h"
#include "program.hpp"
#include "saw_stamps.hpp"
#include "security_option.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::uint32_t kRpdo1Base = 0x200;
constexpr double kLengthScale = 0.0001;  // 6002h: 0.1 mm

// Waits for RPDO1 of the node carrying this product length (6002h, bytes 4..7); its receive
// time, or nothing after the timeout.
std::optional<std::int64_t> await_rpdo(lb::can::Bus& bus, std::uint8_t node, std::uint32_t length_raw,
                                       std::chrono::milliseconds timeout) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    for (;;) {
      auto f = bus.receive();
      if (!f || !f->has_value()) break;
      const auto& frame = **f;
      if (!frame.error && frame.id == kRpdo1Base + node && frame.len == 8 &&
          bench::get_le32(&frame.data[4]) == length_raw) {
        return frame.timestamp_ns;  // CLOCK_REALTIME when receive() took it
      }
    }
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) return std::nullopt;
    pollfd p{bus.fd(), POLLIN, 0};
    ::poll(&p, 1, static_cast<int>(left));
  }
}

}  // namespace

int main(int argc, char** argv) {
  bench::Program program{"bench-setpoint", "latency of a saw set value from a DDS write to its RPDO1 on the bus"};
  auto& cli = program.cli;
  std::uint64_t count = 2000;
  std::uint64_t warmup = 100;
  double warmup_timeout_s = 60;
  int gap_min_us = 1000, gap_max_us = 3000;
  program.add_prefix();
  program.add_domain();
  cli.add_option("--count", count, "timed set values")->capture_default_str();
  cli.add_option("--warmup", warmup, "set values that must arrive before timing starts")->capture_default_str();
  cli.add_option("--warmup-timeout", warmup_timeout_s, "seconds for the warm-up (device boot included)")
      ->capture_default_str();
  cli.add_option("--gap-min-us", gap_min_us)->capture_default_str();
  cli.add_option("--gap-max-us", gap_max_us)->capture_default_str();
  program.add_out();
  program.add_ready("the bus is open");
  program.add_go("start");
  program.add_security();
  if (auto rc = program.parse(argc, argv)) return *rc;

  // The bus first: this process hosts the hub, whoever starts next.
  auto bus = lb::can::open_bus(bench::bus_uri(program.prefix, 0));
  if (!bus) return program.fail(bus.error().message);
  program.ready();
  auto dds = lb::ddsl::Participant::create(bench::participant_options(program, program.name()));
  if (!dds) return program.fail(dds.error().message);
  const std::string device = bench::device_name(0, 0);
  const std::uint8_t node = bench::node_id(0);
  auto writer = (*dds)->writer<msg::SawSetpointPubSubType>(lb::ddsl::topic_name(bench::kLine, device, "setpoint"),
                                                           lb::ddsl::QosKind::command);
  if (!writer) return program.fail(writer.error().message);
  if (!program.go()) return 1;
  const auto match_deadline = Clock::now() + 60s;
  while (writer->matched() == 0) {
    if (Clock::now() > match_deadline) {
      return program.fail("nobody subscribes to " + device + "'s set values");
    }
    std::this_thread::sleep_for(10ms);
  }

  std::mt19937 rng(42);
  std::uniform_int_distribution<int> gap(gap_min_us, gap_max_us);
  std::uint32_t length_raw = 10000;  // 1 m, then 0.1 mm more for every set value
  msg::SawSetpoint sp;
  sp.saw_program_on(true);
  sp.count_mode(msg::SMOOTH_PIPE);
  sp.sync_speed_percent(50.0);
  const auto send_one = [&](std::chrono::milliseconds timeout) -> std::optional<std::int64_t> {
    ++length_raw;
    sp.request_id(length_raw);
    sp.product_length_m(static_cast<double>(length_raw) * kLengthScale);
    const auto t0 = bench::realtime_ns();
    if (!writer->write(sp)) return std::nullopt;
    const auto t1 = await_rpdo(**bus, node, length_raw, timeout);
    if (!t1) return std::nullopt;
    return *t1 - t0;
  };

  // Warm-up: the device may still be booting (set values to an offline saw are refused).
  std::uint64_t warm = 0;
  const auto warm_deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                                std::chrono::duration<double>(warmup_timeout_s));
  while (warm < warmup) {
    if (Clock::now() > warm_deadline) {
      std::fprintf(stderr, "bench-setpoint: only %llu of %llu warm-up set values reached the bus\n",
                   static_cast<unsigned long long>(warm), static_cast<unsigned long long>(warmup));
      return 1;
    }
    if (send_one(300ms)) {
      ++warm;
    } else {
      std::this_thread::sleep_for(100ms);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(gap(rng)));
  }

  std::vector<std::int64_t> latencies;
  latencies.reserve(count);
  std::uint64_t lost = 0;
  for (std::uint64_t i = 0; i < count; ++i) {
    if (auto l = send_one(1000ms)) {
      latencies.push_back(*l);
    } else {
      ++lost;
    }
    std::this_thread::sleep_for(std::chrono::microseconds(gap(rng)));
  }
  program.save_latencies(latencies);
  std::fputs(fmt::format("setpoint_sent={}\nsetpoint_lost={}\n", count, lost).c_str(), stdout);
  std::fputs(bench::format_summary("setpoint", bench::summarize(latencies)).c_str(), stdout);
  return lost == 0 ? 0 : 3;
}
