#pragma once
// One thread per bus: epoll over the bus, timerfds and an eventfd for work posted from other
// threads. Every CANopen service of a bus runs on this thread, so none of them needs a lock.

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "base/result.hpp"
#include "can/bus.hpp"
#include "canopen/cob_id.hpp"

namespace lb::canopen {

class BusLoop {
 public:
  using FrameHandler = std::function<void(const can::CanFrame&)>;
  using Task = std::function<void()>;
  using TimerId = std::size_t;
  using FlushId = std::size_t;

  explicit BusLoop(std::unique_ptr<can::Bus> bus);
  ~BusLoop();
  BusLoop(const BusLoop&) = delete;
  BusLoop& operator=(const BusLoop&) = delete;

  // Registration: before start() or on the loop thread.
  void on_frame(std::uint32_t cob_id, FrameHandler handler);  // 11-bit identifiers
  void on_extended_frame(std::uint32_t id, FrameHandler handler);  // 29-bit identifiers (PDOs so configured)
  void on_other_frame(FrameHandler handler);                  // RTR, error and unclaimed 29-bit frames
  TimerId create_timer(Task callback);
  // period zero = one-shot. Re-arming replaces the previous schedule. Loop thread (or before start).
  void arm_timer(TimerId id, std::chrono::nanoseconds first, std::chrono::nanoseconds period = {});
  void disarm_timer(TimerId id);

  // Work deferred to the end of a burst of received frames: a gateway that decodes several PDOs of
  // one device in one burst publishes one sample for all of them instead of one per frame, which is
  // what keeps a fully loaded bus affordable (a DDS write costs several times a frame's decoding).
  // A burst is what one wake-up finds pending, at most kBurstFrames frames, so a quiet bus flushes
  // after every frame and adds no latency. Registration: before start() or on the loop thread.
  static constexpr int kBurstFrames = 64;
  FlushId create_flush(Task callback);
  // Loop thread: runs the callback once after the frames being dispatched now; at once when called
  // outside frame dispatch. Requests before that run coalesce into one call.
  void request_flush(FlushId id);

  // Any thread: runs the task on the loop thread, in posting order.
  void post(Task task);

  // Loop thread: transmits, counting and logging failures (the caller decides nothing on them).
  Result<void> send(const can::CanFrame& frame);

  void start();
  void stop();  // idempotent; joins the thread
  bool on_loop_thread() const { return std::this_thread::get_id() == thread_.get_id(); }

  // Any thread: how many times the loop has woken up (epoll) so far. A service watchdog feeds
  // systemd only while this grows on every bus; arm a periodic timer so an idle loop still wakes.
  std::uint64_t iterations() const { return iterations_.load(std::memory_order_relaxed); }

  const can::Bus& bus() const { return *bus_; }
  can::BusStats stats() const { return bus_->stats(); }
  // Bits on the wire without stuffing, for the bus load (loop thread).
  std::uint64_t bits_in() const { return bits_in_; }
  std::uint64_t bits_out() const { return bits_out_; }

 private:
  struct Timer {
    int fd = -1;
    Task callback;
  };

  void run();
  void drain_bus();
  void run_posted();
  void dispatch(const can::CanFrame& frame);
  void run_flushes();

  std::unique_ptr<can::Bus> bus_;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;  // eventfd: posted tasks and stop
  std::vector<std::unique_ptr<Timer>> timers_;
  std::array<std::vector<FrameHandler>, cob::kStandardIdCount> handlers_;
  std::vector<std::pair<std::uint32_t, FrameHandler>> extended_handlers_;  // few: a linear scan
  std::vector<FrameHandler> other_handlers_;
  struct Flush {
    Task callback;
    bool requested = false;
  };
  std::vector<Flush> flushes_;
  std::vector<FlushId> requested_flushes_;
  bool in_burst_ = false;
  std::uint64_t error_frames_logged_ = 0;
  std::uint64_t bits_in_ = 0;
  std::uint64_t bits_out_ = 0;

  std::mutex posted_mutex_;
  std::vector<Task> posted_;
  bool stopping_ = false;  // guarded by posted_mutex_
  std::atomic<std::uint64_t> iterations_{0};
  std::thread thread_;
};

}  // namespace lb::canopen
