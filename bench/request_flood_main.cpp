// bench-request-flood: several applications flooding the bridge's services and set values for as
// long as the soak lasts. Each service client (its own participant, as an HMI would be) calls one
// request after another without pause, hostile ones among them (an unknown device, a 10 kB device
// name, an unknown command or parameter, SDO reads of the bench saws); each set-value writer writes
// saw set values as fast as its writer takes them (NaN, ±inf and huge values among them) and never
// waits for a result. At the end it prints what was sent and answered, and what the bridge's
// diagnostics counted (requests refused at a full loop queue, commands lost), as key=value lines.
#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "program.hpp"

namespace bench = lb::bench;
namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

struct Counts {
  std::atomic<std::uint64_t> sent{0}, answered{0}, refused{0}, no_answer{0}, written{0}, write_failed{0};
};

template <class Req, class Rep>
void call_one(lb::ddsl::ServiceClient<Req, Rep>& client, const typename Req::type& request, Counts& counts) {
  ++counts.sent;
  auto r = client.call(request, 2s);
  if (!r) {
    ++counts.no_answer;
    return;
  }
  ++counts.answered;
  if (!r->success()) ++counts.refused;
}

// One application calling services back to back until the deadline.
void service_client(int id, std::uint32_t domain, int devices, Clock::time_point deadline, Counts& counts) {
  auto dds = lb::ddsl::Participant::create({domain, true, fmt::format("bench-request-flood-{}", id)});
  if (!dds) {
    std::fprintf(stderr, "bench-request-flood: %s\n", dds.error().message.c_str());
    return;
  }
  using SdoRead = lb::ddsl::ServiceClient<srv::SdoRead_RequestPubSubType, srv::SdoRead_ResponsePubSubType>;
  using Command = lb::ddsl::ServiceClient<srv::Command_RequestPubSubType, srv::Command_ResponsePubSubType>;
  using GetParameter =
      lb::ddsl::ServiceClient<srv::GetParameter_RequestPubSubType, srv::GetParameter_ResponsePubSubType>;
  auto sdo = SdoRead::create(**dds, lb::ddsl::line_service_path(bench::kLine, "sdo_read"));
  auto command = Command::create(**dds, lb::ddsl::line_service_path(bench::kLine, "command"));
  auto parameter = GetParameter::create(**dds, lb::ddsl::line_service_path(bench::kLine, "get_parameter"));
  if (!sdo || !command || !parameter) {
    std::fprintf(stderr, "bench-request-flood: cannot create the service clients\n");
    return;
  }
  std::mt19937 rng(static_cast<unsigned>(id) * 7919u + 1u);
  const std::string huge(10 * 1024, 'x');
  for (std::uint64_t n = 0; Clock::now() < deadline; ++n) {
    const std::string device = bench::device_name(0, static_cast<int>(rng() % static_cast<unsigned>(devices)));
    switch (n % 6) {
      case 0: {  // a saw's device type (1000h)
        srv::SdoRead_Request r;
        r.device(device);
        r.index(0x1000);
        r.sub_index(0);
        r.data_type("u32");
        call_one(**sdo, r, counts);
        break;
      }
      case 1: {  // a device that does not exist
        srv::SdoRead_Request r;
        r.device("no-such-device");
        r.index(0x1018);
        r.sub_index(1);
        r.data_type("u32");
        call_one(**sdo, r, counts);
        break;
      }
      case 2: {  // 10 kB device name and data type
        srv::SdoRead_Request r;
        r.device(huge);
        r.index(0xFFFF);
        r.sub_index(0xFF);
        r.data_type(huge);
        call_one(**sdo, r, counts);
        break;
      }
      case 3: {  // a command no profile has
        srv::Command_Request r;
        r.device(device);
        r.command("self_destruct");
        call_one(**command, r, counts);
        break;
      }
      case 4: {
        srv::GetParameter_Request r;
        r.device(device);
        r.parameter(n % 12 == 4 ? huge : "saw_cut_depth");
        call_one(**parameter, r, counts);
        break;
      }
      default: {  // a real pulse: the bridge must refuse it at once while the saw is not started
        srv::Command_Request r;
        r.device(device);
        r.command("manual_cut");
        call_one(**command, r, counts);
        break;
      }
    }
  }
}

// One application writing set values as fast as its writer takes them.
void setpoint_writer(int id, std::uint32_t domain, int devices, Clock::time_point deadline, Counts& counts) {
  auto dds = lb::ddsl::Participant::create({domain, true, fmt::format("bench-setpoint-flood-{}", id)});
  if (!dds) {
    std::fprintf(stderr, "bench-request-flood: %s\n", dds.error().message.c_str());
    return;
  }
  std::vector<lb::ddsl::Writer<msg::SawSetpointPubSubType>> writers;
  for (int d = 0; d < devices; ++d) {
    auto w = (*dds)->writer<msg::SawSetpointPubSubType>(lb::ddsl::topic_name(bench::kLine, bench::device_name(0, d),
                                                                             "setpoint"),
                                                        lb::ddsl::QosKind::command);
    if (!w) {
      std::fprintf(stderr, "bench-request-flood: %s\n", w.error().message.c_str());
      return;
    }
    writers.push_back(*w);
  }
  std::this_thread::sleep_for(2s);  // discovery
  const double hostile[] = {std::numeric_limits<double>::quiet_NaN(),
                            std::numeric_limits<double>::infinity(),
                            -std::numeric_limits<double>::infinity(),
                            1e308,
                            -1.0,
                            55.0,
                            12.5};
  std::mt19937 rng(static_cast<unsigned>(id) * 104729u + 3u);
  for (std::uint64_t n = 0; Clock::now() < deadline; ++n) {
    msg::SawSetpoint s;
    s.request_id(n);
    s.saw_program_on(n % 2 == 0);
    s.count_mode(static_cast<msg::SawCountMode>(rng() % 4));  // 2 and 3 are modes the IDL does not name
    s.sync_speed_percent(hostile[rng() % std::size(hostile)]);
    s.product_length_m(hostile[rng() % std::size(hostile)]);
    if (writers[n % writers.size()].write(s)) {
      ++counts.written;
    } else {
      ++counts.write_failed;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  bench::Program program{"bench-request-flood",
                         "service calls and set values from several applications, as fast as they go"};
  auto& cli = program.cli;
  int clients = 3;
  int writers = 2;
  double duration_s = 60;
  program.add_devices("saws on bus 0");
  program.add_domain();
  cli.add_option("--clients", clients, "service-calling applications")->check(CLI::Range(0, 32))->capture_default_str();
  cli.add_option("--writers", writers, "set-value-writing applications")
      ->check(CLI::Range(0, 32))
      ->capture_default_str();
  cli.add_option("--duration", duration_s, "seconds")->check(CLI::Range(1.0, 86400.0))->capture_default_str();
  if (auto rc = program.parse(argc, argv)) return *rc;
  const int devices = program.devices;
  const int domain = program.domain;

  const auto dom = static_cast<std::uint32_t>(domain);
  // The bridge's own count of what it refused and lost, from its diagnostics (state: the latest).
  auto observer = lb::ddsl::Participant::create({dom, true, "bench-request-flood-observer"});
  if (!observer) return program.fail(observer.error().message);
  std::mutex diag_mutex;
  msg::Diagnostics last_diag;
  bool have_diag = false;
  if (auto r = (*observer)->subscribe<msg::DiagnosticsPubSubType>(
          lb::ddsl::topic_name(bench::kLine, lb::ddsl::kBridgeNamespace, "diagnostics"), lb::ddsl::QosKind::state,
          [&](const msg::Diagnostics& d, const auto&) {
            std::lock_guard lock(diag_mutex);
            last_diag = d;
            have_diag = true;
          });
      !r) {
    std::fprintf(stderr, "bench-request-flood: %s\n", r.error().message.c_str());
    return 1;
  }

  const auto start = Clock::now();
  const auto deadline = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(duration_s));
  Counts counts;
  std::vector<std::thread> threads;
  for (int i = 0; i < clients; ++i) threads.emplace_back(service_client, i, dom, devices, deadline, std::ref(counts));
  for (int i = 0; i < writers; ++i) threads.emplace_back(setpoint_writer, i, dom, devices, deadline, std::ref(counts));
  for (auto& t : threads) t.join();
  const double elapsed = std::chrono::duration<double>(Clock::now() - start).count();
  std::this_thread::sleep_for(2500ms);  // the next diagnostics sample (every second)

  std::string out = fmt::format(
      "flood_clients={}\nflood_writers={}\nflood_seconds={:.1f}\nflood_requests_sent={}\nflood_requests_answered={}\n"
      "flood_requests_refused={}\nflood_requests_unanswered={}\nflood_requests_per_s={:.1f}\nflood_setpoints_written={}"
      "\n"
      "flood_setpoints_write_failed={}\nflood_setpoints_per_s={:.1f}\n",
      clients, writers, elapsed, counts.sent.load(), counts.answered.load(), counts.refused.load(),
      counts.no_answer.load(), static_cast<double>(counts.sent.load()) / elapsed, counts.written.load(),
      counts.write_failed.load(), static_cast<double>(counts.written.load()) / elapsed);
  {
    std::lock_guard lock(diag_mutex);
    out += fmt::format("flood_diagnostics_seen={}\n", have_diag ? 1 : 0);
    if (have_diag) {
      std::uint64_t refused = 0;
      for (const auto& b : last_diag.buses()) refused += b.requests_refused();
      out += fmt::format("flood_bridge_requests_refused={}\nflood_bridge_commands_lost={}\n", refused,
                         last_diag.commands_lost());
    }
  }
  std::fputs(out.c_str(), stdout);
  return 0;
}
