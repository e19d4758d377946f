// bench-iceoryx-hop: the same ping-pong as bench-channel-hop, through iceoryx (Debian's
// libiceoryx-posh-dev 2.0.3) instead of the Unix socket: the "bus side" publishes a 128-byte
// sample, the "DDS side" (a second process) waits on a WaitSet, times it and publishes it back;
// the bus side times the echo on its own WaitSet thread. Needs the RouDi daemon (iox-roudi)
// running. Built only with -DLINEBRIDGE_BENCH_ICEORYX=ON: iceoryx is no part of the product; this
// is here to decide the channel's mechanism by measurement (issue 25).
//
// Prints the same key=value lines as bench-channel-hop (hop_mechanism=iceoryx).
#include <sys/wait.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <ctime>
#include <mutex>
#include <thread>
#include <vector>

#include "clock.hpp"
#include "hop_figures.hpp"
#include "iceoryx_posh/popo/publisher.hpp"
#include "iceoryx_posh/popo/subscriber.hpp"
#include "iceoryx_posh/popo/wait_set.hpp"
#include "iceoryx_posh/runtime/posh_runtime.hpp"
#include "latencies.hpp"

namespace bench = lb::bench;

namespace {

struct Hop {
  std::int64_t seq = 0;
  std::int64_t published = 0;  // bus side
  std::int64_t echoed = 0;     // DDS side
  std::uint8_t fill[104]{};    // 128 bytes, as bench-channel-hop's default
};

// Every sample the subscriber holds, in order, to on_sample (what a WaitSet wake-up announced).
template <class OnSample>
void take_all(iox::popo::Subscriber<Hop>& sub, OnSample on_sample) {
  for (bool got = true; got;) {
    got = false;
    sub.take().and_then([&](auto& s) {
      got = true;
      on_sample(*s);
    });
  }
}

// The echoing side: every Status sample back as a Set sample; its bus -> DDS times to `out`.
int dds_side(std::uint64_t total, const char* out) {
  iox::runtime::PoshRuntime::initRuntime("bench-iceoryx-hop-dds");
  iox::popo::SubscriberOptions so;
  so.queueCapacity = 16;
  iox::popo::Subscriber<Hop> sub({"Bench", "Hop", "Status"}, so);
  iox::popo::Publisher<Hop> pub({"Bench", "Hop", "Set"});
  iox::popo::WaitSet<> ws;
  ws.attachState(sub, iox::popo::SubscriberState::HAS_DATA).or_else([](auto) { std::exit(1); });
  std::vector<std::int64_t> lat;
  lat.reserve(total);
  std::uint64_t last = 0;
  while (last < total) {
    auto n = ws.timedWait(iox::units::Duration::fromSeconds(5));
    if (n.empty()) break;
    take_all(sub, [&](const Hop& s) {
      const auto now = bench::monotonic_ns();
      lat.push_back(now - s.published);
      last = static_cast<std::uint64_t>(s.seq);
      pub.loan().and_then([&](auto& e) {
        *e = s;
        e->echoed = bench::monotonic_ns();
        e.publish();
      });
    });
  }
  return bench::write_latencies(out, lat) ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli{"bench-iceoryx-hop: one sample's latency through an iceoryx publisher/subscriber pair and back"};
  bench::HopRun run;
  run.add(cli);
  CLI11_PARSE(cli, argc, argv);
  const std::uint64_t total = run.total();
  char out[] = "/tmp/iceoryx-hop.XXXXXX";
  const int fd = ::mkstemp(out);
  if (fd < 0) return 1;
  ::close(fd);

  const pid_t child = ::fork();
  if (child == 0) ::_exit(dds_side(total, out));

  iox::runtime::PoshRuntime::initRuntime("bench-iceoryx-hop-bus");
  iox::popo::Publisher<Hop> pub({"Bench", "Hop", "Status"});
  iox::popo::SubscriberOptions so;
  so.queueCapacity = 16;
  iox::popo::Subscriber<Hop> sub({"Bench", "Hop", "Set"}, so);
  iox::popo::WaitSet<> ws;
  ws.attachState(sub, iox::popo::SubscriberState::HAS_DATA).or_else([](auto) { std::exit(1); });

  // The echo is taken on a thread of its own, as the bridge's channel thread takes set values.
  std::atomic<std::int64_t> echoed_seq{-1};
  std::vector<std::int64_t> rtt, dds2bus;
  rtt.reserve(total);
  dds2bus.reserve(total);
  std::atomic<bool> done{false};
  std::mutex m;
  std::condition_variable cv;
  std::thread reader([&] {
    while (!done) {
      auto n = ws.timedWait(iox::units::Duration::fromMilliseconds(100));
      if (n.empty()) continue;
      take_all(sub, [&](const Hop& s) {
        const auto now = bench::monotonic_ns();
        if (s.seq > 0) {
          rtt.push_back(now - s.published);
          dds2bus.push_back(now - s.echoed);
        }
        {
          std::lock_guard lock(m);
          echoed_seq.store(s.seq);
        }
        cv.notify_one();
      });
    }
  });

  auto send = [&](std::int64_t seq) {
    pub.loan().and_then([&](auto& s) {
      s->seq = seq;
      s->published = bench::monotonic_ns();
      s.publish();
    });
  };
  // Until the other side is subscribed and echoes.
  while (echoed_seq.load() < 0) {
    send(0);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    if (int st = 0; ::waitpid(child, &st, WNOHANG) == child) {
      std::fprintf(stderr, "bench-iceoryx-hop: the echoing side ended before it answered\n");
      done = true;
      reader.join();
      return 1;
    }
  }
  std::uint64_t lost = 0;
  for (std::uint64_t seq = 1; seq <= total; ++seq) {
    std::this_thread::sleep_for(std::chrono::microseconds(run.interval_us));
    send(static_cast<std::int64_t>(seq));
    std::unique_lock lock(m);
    if (!cv.wait_for(lock, std::chrono::seconds(1),
                     [&] { return echoed_seq.load() == static_cast<std::int64_t>(seq); }))
      ++lost;
  }
  done = true;
  reader.join();
  int st = 0;
  ::waitpid(child, &st, 0);
  auto b2d = bench::read_latencies(out);
  ::unlink(out);
  bench::keep_last(rtt, run.count);
  bench::keep_last(dds2bus, run.count);
  bench::keep_last(b2d, run.count);
  std::printf("hop_mechanism=iceoryx\nhop_samples=%zu\nhop_lost=%llu\nhop_payload_bytes=%zu\n", rtt.size(),
              static_cast<unsigned long long>(lost), sizeof(Hop));
  bench::print_hop("bus2dds", b2d);
  bench::print_hop("dds2bus", dds2bus);
  bench::print_hop("rtt", rtt);
  return lost == 0 ? 0 : 1;
}
