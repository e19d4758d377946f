#pragma once
// A mutex with priority inheritance (PTHREAD_PRIO_INHERIT). The bus loops may run SCHED_FIFO and
// publish to the channel under its lock; the channel's own thread runs at normal priority. With a
// plain mutex, a channel thread preempted while holding the lock would hold a realtime bus loop
// (and its SYNC) for as long as other normal-priority work runs; with inheritance the holder runs
// at the waiter's priority until it unlocks.

#include <pthread.h>

namespace lb::link {

class PiMutex {
 public:
  PiMutex() noexcept {
    pthread_mutexattr_t attr;
    pthread_mutexattr_init(&attr);
    pthread_mutexattr_setprotocol(&attr, PTHREAD_PRIO_INHERIT);
    pthread_mutex_init(&mutex_, &attr);
    pthread_mutexattr_destroy(&attr);
  }
  ~PiMutex() { pthread_mutex_destroy(&mutex_); }
  PiMutex(const PiMutex&) = delete;
  PiMutex& operator=(const PiMutex&) = delete;

  void lock() noexcept { pthread_mutex_lock(&mutex_); }
  void unlock() noexcept { pthread_mutex_unlock(&mutex_); }
  bool try_lock() noexcept { return pthread_mutex_trylock(&mutex_) == 0; }

 private:
  pthread_mutex_t mutex_;
};

}  // namespace lb::link
