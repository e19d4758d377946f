#pragma once
// The executables run until SIGINT/SIGTERM or an optional duration. Signals are blocked in every
// thread (call block_stop_signals() before starting any) and taken synchronously here, so no
// handler touches shared state. SIGUSR1 is the process's own wake-up: a part that failed for good
// (a bus loop) raises it to end the wait (request_stop()).

#include <unistd.h>

#include <chrono>
#include <csignal>

namespace lb::app {

inline sigset_t stop_signals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGUSR1);
  return set;
}

inline void block_stop_signals() {
  const sigset_t set = stop_signals();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

// Any thread: ends run_until_signal() (with SIGUSR1).
inline void request_stop() { ::kill(::getpid(), SIGUSR1); }

// Returns the signal number, or 0 when the duration elapsed. duration zero = no limit.
inline int run_until_signal(std::chrono::milliseconds duration) {
  const sigset_t set = stop_signals();
  if (duration.count() <= 0) {
    int sig = 0;
    sigwait(&set, &sig);
    return sig;
  }
  const auto s = std::chrono::duration_cast<std::chrono::seconds>(duration);
  const timespec ts{static_cast<time_t>(s.count()), static_cast<long>((duration - s).count() * 1'000'000)};
  const int sig = sigtimedwait(&set, nullptr, &ts);
  return sig > 0 ? sig : 0;
}

}  // namespace lb::app
