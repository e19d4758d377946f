// bench-channel-hop: what the hop between a line's bus process and its DDS process costs by
// itself (issue 25 deliverable 3), without CAN or DDS around it. The real link::BusChannel (the
// bus side: publish() from a "bus loop" thread, the channel's own thread does the socket work)
// and the real link::DdsChannel (the DDS side: a blocking receive loop) in two processes over the
// same Unix SOCK_SEQPACKET socket the bridge uses. The DDS side echoes every sample back on a
// reader endpoint, as a set value comes back to the bus side.
//
// One sample in flight at a time (ping-pong, --interval-us apart): every figure is one sample's
// latency, not a batch's. Each sample carries the time it was published (CLOCK_MONOTONIC, the same
// clock in both processes): the DDS side times bus -> DDS when receive() returns it, the bus side
// times DDS -> bus and the round trip when its reader's handler runs.
//
// Prints key=value lines: hop_{bus2dds,dds2bus,rtt}_{p50,p99,p999,max}_us, hop_samples, hop_lost.
// No DDS participant: it may run anywhere (bench.sh runs it in its namespace like everything).
#include <fmt/format.h>
#include <sys/wait.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "clock.hpp"
#include "hop_figures.hpp"
#include "latencies.hpp"
#include "link/bus_channel.hpp"
#include "link/dds_channel.hpp"

namespace bench = lb::bench;
namespace lk = lb::link;
using namespace std::chrono_literals;

namespace {

constexpr std::uint32_t kStatusId = 0;  // bus -> dds (a state endpoint, as a saw's status)
constexpr std::uint32_t kSetId = 1;     // dds -> bus (a reader, as a set value)

// Payload: [0..8) the sequence number, [8..16) the bus side's publish time, [16..24) the DDS
// side's send time (the echo), the rest filler (a saw status's CDR is ~100 bytes).
void put(std::vector<std::uint8_t>& p, std::size_t at, std::int64_t v) { std::memcpy(p.data() + at, &v, sizeof v); }
std::int64_t take(const std::vector<std::uint8_t>& p, std::size_t at) {
  std::int64_t v = 0;
  std::memcpy(&v, p.data() + at, sizeof v);
  return v;
}

// The DDS side: connect, wait for Ready, echo every status sample as a set-value sample. Writes
// its bus -> DDS latencies (ns, one a line) to `out` at the end.
int dds_side(const std::string& path, const std::string& out, std::uint64_t expect) {
  std::unique_ptr<lk::DdsChannel> channel;
  for (int i = 0; i < 500 && !channel; ++i) {
    if (auto c = lk::DdsChannel::connect(path, 100))
      channel = std::move(*c);
    else
      std::this_thread::sleep_for(10ms);
  }
  if (!channel) {
    std::fprintf(stderr, "bench-channel-hop (dds side): cannot connect to %s\n", path.c_str());
    return 1;
  }
  std::vector<std::int64_t> lat;
  lat.reserve(expect);
  bool ready = false;
  std::uint32_t status_id = kStatusId, set_id = kSetId;  // as the bus side declared them
  for (;;) {
    auto m = channel->receive(2000);
    if (!m) break;  // the bus side closed: done
    if (!*m) continue;
    if (std::holds_alternative<lk::Ready>(**m)) ready = true;
    if (const auto* d = std::get_if<lk::Declare>(&**m)) (d->writer ? status_id : set_id) = d->id;
    auto* s = std::get_if<lk::Sample>(&**m);
    if (!s || !ready || s->id != status_id) continue;
    const auto now = bench::monotonic_ns();
    lat.push_back(now - take(s->payload, 8));
    lk::Sample echo;
    echo.id = set_id;
    echo.payload = std::move(s->payload);
    put(echo.payload, 16, bench::monotonic_ns());
    channel->send(echo);
    // The last one: done (the bus side's stop() does not close an accepted channel at once).
    if (static_cast<std::uint64_t>(take(echo.payload, 0)) >= expect) break;
  }
  return bench::write_latencies(out, lat) ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"bench-channel-hop: one sample's latency through lk::BusChannel -> lk::DdsChannel and back"};
  bench::HopRun run;
  std::size_t size = 128;
  std::string dir = "/tmp";
  bool latest = true;
  run.add(cli);
  cli.add_option("--size", size, "payload bytes (>= 24)")->check(CLI::Range(24, 60000))->capture_default_str();
  cli.add_option("--dir", dir, "where the socket goes (a private directory is made in it)")->capture_default_str();
  cli.add_option("--latest", latest,
                 "the bus -> DDS endpoint keeps only its latest sample (as status does); false: queued, as events")
      ->capture_default_str();
  CLI11_PARSE(cli, argc, argv);

  char tmpl[4096];
  std::snprintf(tmpl, sizeof tmpl, "%s/channel-hop.XXXXXX", dir.c_str());
  if (!::mkdtemp(tmpl)) {
    std::perror("mkdtemp");
    return 1;
  }
  const std::string private_dir = tmpl;
  const std::string path = private_dir + "/channel.sock";
  const std::string dds_out = private_dir + "/bus2dds.lat";
  const std::uint64_t total = run.total();

  // The bus side first (it listens), then the DDS side in a child process (forked before any
  // thread exists in this one).
  auto opened = lk::BusChannel::open({path, "bench", 1});
  if (!opened) {
    std::fprintf(stderr, "bench-channel-hop: %s\n", opened.error().message.c_str());
    return 1;
  }
  const pid_t child = ::fork();
  if (child < 0) {
    std::perror("fork");
    return 1;
  }
  if (child == 0) {
    // The child never runs the BusChannel's destructor (it would stop a channel it does not own).
    ::_exit(dds_side(path, dds_out, total));
  }
  auto& bus = **opened;

  std::mutex m;
  std::condition_variable cv;
  std::uint64_t echoed = 0;  // the sequence number of the last echo
  std::vector<std::int64_t> rtt, dds2bus;
  rtt.reserve(total);
  dds2bus.reserve(total);
  lk::Declare status{kStatusId,       true, false, 0, 0, static_cast<std::uint32_t>(size), "rt/bench/hop/status",
                     "bench::Status", ""};
  lk::Declare set{kSetId, false, false, 0, 0, static_cast<std::uint32_t>(size), "rt/bench/hop/set", "bench::Set", ""};
  const auto status_id = bus.declare(status, latest);
  bus.declare_reader(set, [&](const lk::Sample& s) {
    const auto now = bench::monotonic_ns();
    if (s.payload.size() < 24) return;
    std::lock_guard lock(m);
    rtt.push_back(now - take(s.payload, 8));
    dds2bus.push_back(now - take(s.payload, 16));
    echoed = static_cast<std::uint64_t>(take(s.payload, 0));
    cv.notify_one();
  });
  bus.start();

  std::vector<std::uint8_t> payload(size, 0x5a);
  std::uint64_t lost = 0;
  // Until the DDS side is connected and ready: samples until the first echo (not counted).
  for (bool up = false; !up;) {
    put(payload, 0, 0);
    put(payload, 8, bench::monotonic_ns());
    bus.publish(status_id, payload);
    std::unique_lock lock(m);
    up = cv.wait_for(lock, 20ms, [&] { return !rtt.empty(); });
    if (int st = 0; ::waitpid(child, &st, WNOHANG) == child) {
      std::fprintf(stderr, "bench-channel-hop: the DDS side ended before it answered\n");
      return 1;
    }
  }
  {
    std::lock_guard lock(m);
    rtt.clear();
    dds2bus.clear();
  }
  for (std::uint64_t seq = 1; seq <= total; ++seq) {
    std::this_thread::sleep_for(std::chrono::microseconds(run.interval_us));
    put(payload, 0, static_cast<std::int64_t>(seq));
    put(payload, 8, bench::monotonic_ns());
    bus.publish(status_id, payload);
    std::unique_lock lock(m);
    if (!cv.wait_for(lock, 1s, [&] { return echoed == seq; })) ++lost;
  }
  bus.stop();  // the DDS side sees the channel close and writes its figures
  int st = 0;
  ::waitpid(child, &st, 0);

  auto b2d = bench::read_latencies(dds_out);
  std::filesystem::remove_all(private_dir);
  std::lock_guard lock(m);
  bench::keep_last(rtt, run.count);
  bench::keep_last(dds2bus, run.count);
  bench::keep_last(b2d, run.count);
  std::printf("hop_mechanism=unix_seqpacket\nhop_samples=%zu\nhop_lost=%llu\nhop_payload_bytes=%zu\n", rtt.size(),
              static_cast<unsigned long long>(lost), size);
  bench::print_hop("bus2dds", b2d);
  bench::print_hop("dds2bus", dds2bus);
  bench::print_hop("rtt", rtt);
  const auto c = bus.counters();
  std::printf("hop_channel_dropped=%llu\n", static_cast<unsigned long long>(c.dropped_queue_full + c.dropped_no_peer));
  return lost == 0 ? 0 : 1;
}
