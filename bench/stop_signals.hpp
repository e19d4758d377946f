#pragma once
// SIGINT and SIGTERM as a question the main loop asks ("has bench.sh asked us to stop?") instead
// of a handler writing a global flag. Make it before any thread starts: threads inherit the
// blocked mask, so the signals stay pending for the main thread to collect.

#include <signal.h>

#include <ctime>

namespace lb::bench {

class StopSignals {
 public:
  StopSignals() {
    sigemptyset(&set_);
    sigaddset(&set_, SIGINT);
    sigaddset(&set_, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set_, nullptr);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  // Until one of them arrives.
  void wait() {
    int signal = 0;
    sigwait(&set_, &signal);
    stopped_ = true;
  }

  // True once one of them has arrived; never waits.
  bool requested() {
    if (stopped_) return true;
    const timespec no_wait{};
    stopped_ = sigtimedwait(&set_, nullptr, &no_wait) > 0;
    return stopped_;
  }

 private:
  sigset_t set_{};
  bool stopped_ = false;
};

}  // namespace lb::bench
