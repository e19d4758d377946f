#include "app/service_notifier.hpp"

#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

#include <algorithm>

namespace lb::app {

ServiceNotifier::ServiceNotifier(std::vector<Loop> loops) : loops_(std::move(loops)) {
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0) watchdog_ = std::chrono::microseconds(usec);
  thread_ = std::thread([this] { run(); });
}

ServiceNotifier::~ServiceNotifier() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  thread_.join();
}

void ServiceNotifier::stopping() { sd_notify(0, "STOPPING=1"); }

void ServiceNotifier::restarting(const std::string& why) {
  sd_notifyf(0, "RELOADING=1\nWATCHDOG=1\nSTATUS=%s", why.c_str());
}

std::vector<std::uint64_t> ServiceNotifier::snapshot() const {
  std::vector<std::uint64_t> out;
  for (const auto& l : loops_) out.push_back(l.progress());
  return out;
}

bool ServiceNotifier::wait(std::chrono::steady_clock::duration d) {
  std::unique_lock lock(mutex_);
  return !cv_.wait_for(lock, d, [this] { return stop_; });
}

void ServiceNotifier::run() {
  // Ready once every loop has woken at least once: its thread runs and its timers are armed.
  for (;;) {
    const auto now = snapshot();
    if (std::all_of(now.begin(), now.end(), [](std::uint64_t n) { return n > 0; })) break;
    if (!wait(std::chrono::milliseconds(10))) return;
  }
  // Every loop went round: what a ping says too. A process that started again in place (restarting())
  // has had no ping since its previous image's last, and its first periodic one comes WatchdogSec/2
  // from now.
  sd_notifyf(0, "READY=1\nWATCHDOG=1\nSTATUS=%zu bus loop(s) running", loops_.size());
  if (watchdog_.count() == 0) return;

  const auto period = std::max<std::chrono::steady_clock::duration>(watchdog_ / 2, 4 * kLoopTick);
  auto last = snapshot();
  std::vector<bool> reported(loops_.size(), false);
  while (wait(period)) {
    const auto now = snapshot();
    bool all = true;
    for (std::size_t i = 0; i < loops_.size(); ++i) {
      const bool moved = now[i] != last[i];
      all = all && moved;
      if (!moved && !reported[i]) {
        spdlog::error("bus {}: its loop made no progress for {} ms: the systemd watchdog is no longer fed",
                      loops_[i].name, std::chrono::duration_cast<std::chrono::milliseconds>(period).count());
      } else if (moved && reported[i]) {
        spdlog::warn("bus {}: its loop runs again", loops_[i].name);
      }
      reported[i] = !moved;
    }
    if (all) sd_notify(0, "WATCHDOG=1");
    last = now;
  }
}

}  // namespace lb::app
