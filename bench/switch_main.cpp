// bench-switch: what this machine charges for handing work to another thread and to another
// process, the two hand-overs of the DDS -> CAN path (one process: the Fast DDS listener wakes the
// bus loop, a thread; split: the DDS process wakes the bus process). A byte ping-pongs over two
// pipes between two threads, then between two processes (fork), both on the CPUs given (--cpu: one
// core, as bench.sh pins the bridge). One way = a round trip / 2: a write, a wake-up, a switch
// and a read. The same idea as lmbench's lat_ctx and `perf bench sched pipe`, without the tools.
//
// Prints key=value lines: switch_{thread,process}_oneway_{p50,p99}_us, switch_round_trips.
#include <sched.h>
#include <sys/wait.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

#include "clock.hpp"
#include "latencies.hpp"

namespace {

struct Pipe {
  std::array<int, 2> fd{-1, -1};
  Pipe() {
    if (::pipe(fd.data()) != 0) throw std::runtime_error("pipe");
  }
  ~Pipe() {
    for (const int f : fd) {
      if (f >= 0) ::close(f);
    }
  }
  Pipe(const Pipe&) = delete;
  Pipe& operator=(const Pipe&) = delete;
};

bool transfer(int from, int to) {
  char byte = 0;
  return ::read(from, &byte, 1) == 1 && ::write(to, &byte, 1) == 1;
}

void echo(int from, int to, int round_trips) {
  for (int i = 0; i < round_trips; ++i) {
    if (!transfer(from, to)) return;
  }
}

// Round trips timed from this side (the other side, thread or process, echoes): one way each, in
// ns, half its round trip.
std::vector<std::int64_t> ping(int to, int from, int round_trips) {
  std::vector<std::int64_t> one_way_ns;
  one_way_ns.reserve(static_cast<std::size_t>(round_trips));
  char byte = 1;
  for (int i = 0; i < round_trips; ++i) {
    const auto t0 = lb::bench::monotonic_ns();
    if (::write(to, &byte, 1) != 1 || ::read(from, &byte, 1) != 1) break;
    one_way_ns.push_back((lb::bench::monotonic_ns() - t0) / 2);
  }
  return one_way_ns;
}

void report(const char* what, std::vector<std::int64_t> one_way_ns) {
  const auto s = lb::bench::summarize(std::move(one_way_ns));
  std::printf("switch_%s_oneway_p50_us=%.2f\nswitch_%s_oneway_p99_us=%.2f\n", what, s.p50_us, what, s.p99_us);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App cli("bench-switch: a hand-over to another thread and to another process, one way");
  int round_trips = 50000;
  std::vector<int> cpus;
  cli.add_option("--count", round_trips, "round trips of each kind")
      ->check(CLI::Range(100, 10000000))
      ->capture_default_str();
  cli.add_option("--cpu", cpus, "run both sides on these CPUs (default: wherever the scheduler puts them)");
  CLI11_PARSE(cli, argc, argv);

  if (!cpus.empty()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (const int c : cpus) CPU_SET(c, &set);
    // Threads and forked children inherit it.
    if (::sched_setaffinity(0, sizeof set, &set) != 0) {
      std::perror("bench-switch: sched_setaffinity");
      return 2;
    }
  }
  const int warmup = std::max(100, round_trips / 10);
  {
    Pipe there, back;
    std::thread other([&] { echo(there.fd[0], back.fd[1], warmup + round_trips); });
    ping(there.fd[1], back.fd[0], warmup);
    auto one_way = ping(there.fd[1], back.fd[0], round_trips);
    other.join();
    if (static_cast<int>(one_way.size()) != round_trips) return 1;
    report("thread", std::move(one_way));
  }
  {
    Pipe there, back;
    std::fflush(stdout);
    const pid_t child = ::fork();
    if (child < 0) {
      std::perror("bench-switch: fork");
      return 2;
    }
    if (child == 0) {
      echo(there.fd[0], back.fd[1], warmup + round_trips);
      ::_exit(0);
    }
    ping(there.fd[1], back.fd[0], warmup);
    auto one_way = ping(there.fd[1], back.fd[0], round_trips);
    int status = 0;
    ::waitpid(child, &status, 0);
    if (static_cast<int>(one_way.size()) != round_trips) return 1;
    report("process", std::move(one_way));
  }
  std::printf("switch_round_trips=%d\n", round_trips);
  return 0;
}
