// bench-record-handoff: what recording (record:) costs the bus loop per frame when the disk is too
// slow, beside the SYNC jitter figure, whose host noise can be larger than the effect. A thread at
// realtime priority (the loop) hands frames to a RecordingBus at the bus's rate; the recording goes
// to a FIFO drained at a slow disk's rate; threads at normal priority keep the CPU busy, so the
// recording's own writer thread (normal priority) is often kept waiting. Measured: how long each
// send() through the recording takes on the realtime thread (the frame's hand-off and its line),
// and, as the floor beside it, how late that thread woke. Run it pinned to one core:
//   taskset -c 1 bench-record-handoff --duration 30
#include <fcntl.h>
#include <fmt/format.h>
#include <pthread.h>
#include <sched.h>
#include <sys/eventfd.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "can/recording_bus.hpp"
#include "can/unique_fd.hpp"
#include "clock.hpp"
#include "latencies.hpp"
#include "program.hpp"

namespace bench = lb::bench;

namespace {

// The bus under the recording: takes every frame at once, so only the recording is measured.
class NullBus final : public lb::can::Bus {
 public:
  const std::string& uri() const override { return uri_; }
  int fd() const override { return event_.get(); }
  lb::Result<std::optional<lb::can::CanFrame>> receive() override { return std::optional<lb::can::CanFrame>{}; }
  lb::Result<void> send(const lb::can::CanFrame&) override { return {}; }
  lb::can::BusStats stats() const override { return {}; }

 private:
  std::string uri_ = "virtual:handoff";
  lb::can::UniqueFd event_{::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)};
};

}  // namespace

int main(int argc, char** argv) {
  bench::Program program{"bench-record-handoff", "the bus loop's cost of recording to a slow disk"};
  auto& cli = program.cli;
  double duration_s = 30;
  int rate = 8000;
  int drain_bytes_per_s = 16384;
  int priority = 40;
  int hogs = 2;
  cli.add_option("--duration", duration_s, "seconds to measure")->check(CLI::Range(1.0, 3600.0))->capture_default_str();
  cli.add_option("--rate", rate, "frames/s handed to the recording")
      ->check(CLI::Range(100, 20000))
      ->capture_default_str();
  cli.add_option("--drain", drain_bytes_per_s, "bytes/s the slow disk takes")
      ->check(CLI::Range(1024, 1 << 30))
      ->capture_default_str();
  cli.add_option("--realtime-priority", priority, "SCHED_FIFO priority of the sending thread (0: normal)")
      ->check(CLI::Range(0, 99))
      ->capture_default_str();
  cli.add_option("--hogs", hogs, "busy threads at normal priority")->check(CLI::Range(0, 16))->capture_default_str();
  if (auto rc = program.parse(argc, argv)) return *rc;

  char dir_template[] = "/tmp/record-handoff.XXXXXX";
  const char* dir = ::mkdtemp(dir_template);
  if (dir == nullptr) {
    std::perror("mkdtemp");
    return 1;
  }
  const std::string fifo = std::string(dir) + "/slow-disk.fifo";
  if (::mkfifo(fifo.c_str(), 0600) != 0) {
    std::perror("mkfifo");
    return 1;
  }
  lb::can::UniqueFd reader{::open(fifo.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};
  auto recording = lb::can::RecordingBus::open(std::make_unique<NullBus>(), fifo);
  if (!recording) {
    std::fputs((recording.error().message + "\n").c_str(), stderr);
    return 1;
  }

  std::atomic<bool> done{false};
  std::vector<std::thread> others;
  others.emplace_back([&] {  // the slow disk: a few reads a second
    std::vector<char> buf(static_cast<std::size_t>(drain_bytes_per_s / 16 + 1));
    while (!done) {
      [[maybe_unused]] const auto n = ::read(reader.get(), buf.data(), buf.size());
      std::this_thread::sleep_for(std::chrono::microseconds(62'500));
    }
  });
  for (int i = 0; i < hogs; ++i) {
    others.emplace_back([&] {
      volatile std::uint64_t spin = 0;
      while (!done) spin = spin + 1;
    });
  }

  if (priority > 0) {
    sched_param sp{};
    sp.sched_priority = priority;
    if (const int e = ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &sp); e != 0) {
      program.fail(fmt::format("SCHED_FIFO {} refused ({}): run as root or with CAP_SYS_NICE", priority, e));
      done = true;
      for (auto& t : others) t.join();
      return 1;
    }
  }

  const std::int64_t period_ns = 1'000'000'000 / rate;
  const auto n = static_cast<std::size_t>(duration_s * rate);
  std::vector<std::int64_t> send_ns, late_ns;
  send_ns.reserve(n);
  late_ns.reserve(n);
  lb::can::CanFrame frame;
  frame.id = 0x185;
  frame.len = 8;
  std::int64_t due = bench::monotonic_ns();
  for (std::size_t i = 0; i < n; ++i) {
    due += period_ns;
    const timespec at{static_cast<time_t>(due / 1'000'000'000), static_cast<long>(due % 1'000'000'000)};
    ::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &at, nullptr);
    const std::int64_t t0 = bench::monotonic_ns();
    late_ns.push_back(t0 - due);
    frame.data[0] = static_cast<std::uint8_t>(i);
    [[maybe_unused]] const auto r = (*recording)->send(frame);
    send_ns.push_back(bench::monotonic_ns() - t0);
  }
  const auto errors = (*recording)->stats().record_errors;
  done = true;
  for (auto& t : others) t.join();
  recording->reset();
  ::unlink(fifo.c_str());
  ::rmdir(dir);

  const auto over = [&](std::int64_t ns) {
    return std::count_if(send_ns.begin(), send_ns.end(), [ns](std::int64_t v) { return v > ns; });
  };
  std::string command;  // how it was run, to reproduce it (with taskset -c <cores>)
  for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);
  std::string cores;
  cpu_set_t set;
  CPU_ZERO(&set);
  if (::sched_getaffinity(0, sizeof set, &set) == 0) {
    for (int c = 0; c < CPU_SETSIZE; ++c) {
      if (CPU_ISSET(c, &set)) cores += (cores.empty() ? "" : ",") + std::to_string(c);
    }
  }
  std::fputs(fmt::format("handoff_command=taskset -c {} {}\nhandoff_record_errors={}\nhandoff_send_over_100us={}\n"
                         "handoff_send_over_1ms={}\n",
                         cores, command, errors, over(100'000), over(1'000'000))
                 .c_str(),
             stdout);
  // The hand-off itself, and how late the sending thread woke (the host's noise beside it).
  std::fputs(bench::format_summary("handoff_send", bench::summarize(send_ns)).c_str(), stdout);
  std::fputs(bench::format_summary("handoff_wake", bench::summarize(late_ns)).c_str(), stdout);
  return 0;
}
