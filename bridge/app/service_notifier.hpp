#pragma once
// systemd's notification protocol for the gateway (Type=notify, WatchdogSec=): READY=1 once every
// bus loop has gone round, WATCHDOG=1 only while every bus loop keeps making progress, STOPPING=1
// when the stop begins, RELOADING=1 when the process starts again in place (a bridge that stepped
// back re-executes itself: the same PID, whose next image says READY=1). A stalled loop (a handler
// that blocks, a loop thread that ended) stops the watchdog pings, and systemd restarts the
// service. Outside systemd (no NOTIFY_SOCKET) it sends nothing and costs one idle thread.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace lb::app {

class ServiceNotifier {
 public:
  struct Loop {
    std::string name;
    std::function<std::uint64_t()> progress;  // grows while the loop works (BusLoop::iterations)
  };

  // How often each loop must wake at least (a periodic timer on an idle bus) for the checks to be
  // meaningful; the checks run every WATCHDOG_USEC / 2, and never more often than 4 ticks.
  static constexpr std::chrono::milliseconds kLoopTick{100};

  // Reads WATCHDOG_USEC (sd_watchdog_enabled) and starts checking.
  explicit ServiceNotifier(std::vector<Loop> loops);
  ~ServiceNotifier();  // stops the checks (does not send STOPPING=1: call stopping())
  ServiceNotifier(const ServiceNotifier&) = delete;
  ServiceNotifier& operator=(const ServiceNotifier&) = delete;

  void stopping();
  // The process replaces its image (execv) and goes on: not a stop. systemd shows the unit
  // reloading, with `why` as its status, until the next image's READY=1; its watchdog keeps
  // running, so this pings once more: the next image has a whole WatchdogSec to show its loops.
  void restarting(const std::string& why);

  // The watchdog interval systemd asked for; zero without one.
  std::chrono::microseconds watchdog() const { return watchdog_; }

 private:
  void run();
  std::vector<std::uint64_t> snapshot() const;
  bool wait(std::chrono::steady_clock::duration d);  // false when asked to stop

  std::vector<Loop> loops_;
  std::chrono::microseconds watchdog_{0};
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;
};

}  // namespace lb::app
