#pragma once
// One command for both processes of a line (linebridge --part both, the default: development,
// the demo, the tests): the bus process starts its DDS process as a child and starts another
// whenever it ends, as systemd does for the two units of a line, with the same back-off
// (app/restart_pacing.hpp), and never gives up once a DDS process served. The child dies with its
// parent (PR_SET_PDEATHSIG, set by the child itself: die_with_bus_process()), and is told nothing
// of systemd (the parent is the service).

#include <sys/types.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "app/restart_pacing.hpp"

namespace lb::app {

// The environment variable that tells a DDS process the bus process that started it.
inline constexpr const char* kBusPidEnv = "LINEBRIDGE_BUS_PID";

// For a DDS process, first thing: if a bus process started it (kBusPidEnv), it is killed when
// that process ends. False when that process has ended already (the caller exits).
bool die_with_bus_process();

class DdsSupervisor {
 public:
  // argv: the DDS process's command line (argv[0] an absolute path). served: how many DDS
  // processes the channel has taken so far (BusChannel::Counters::connects). A DDS process that
  // ends is replaced as RestartPacer says (at once while restarts are few, then after a pause
  // doubling from 1 s to 30 s); one that ends before it was served is failing at start-up and
  // waits at least 100 ms doubling to 5 s. report: how each one ended (its pid and exit status),
  // for the line's diagnostics; called on the supervisor's thread.
  using Report = std::function<void(pid_t, std::string)>;
  DdsSupervisor(std::vector<std::string> argv, std::function<std::uint64_t()> served, Report report = {},
                RestartPacing pacing = {});
  ~DdsSupervisor();  // stops: SIGTERM to the child, SIGKILL if it has not ended within 2 s
  DdsSupervisor(const DdsSupervisor&) = delete;
  DdsSupervisor& operator=(const DdsSupervisor&) = delete;

  // The DDS process refused the configuration (exit 2) before any DDS process served: a bad line
  // file or security file at start; the supervisor stops trying and asks the process to stop
  // (request_stop()). Once one served, an exit 2 (a certificate or CRL that expired since, found
  // at a restart) stops nothing: the bus runs on, the reason is reported, and the next start
  // waits as the back-off says, so that a file put right is taken without a restart of the bus.
  bool refused_configuration() const { return refused_; }
  pid_t child() const { return child_.load(); }

 private:
  void run();
  pid_t spawn();

  std::vector<std::string> argv_;
  std::function<std::uint64_t()> served_;
  Report report_;
  RestartPacer pacer_;  // the supervisor's thread only
  std::vector<std::string> env_;
  std::atomic<pid_t> child_{0};
  std::atomic<bool> refused_{false};
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace lb::app
