#pragma once
// One thread per bus: epoll over the bus, timerfds and an eventfd for work posted from other
// threads. Every CANopen service of a bus runs on this thread, so none of them needs a lock.
//
// Every callback (frame handler, timer, posted task, flush) runs behind an exception barrier: a
// throw is logged at a bounded rate and counted (handler_failures), and the loop goes on, so a
// sporadic throw costs one frame or one tick, not the line. A frame handler or timer that throws
// kMaxHandlerFailures times in a row is broken for good: the loop ends through its failure path
// (as when epoll fails), reported to the failure handler, so that the process exits and its
// service manager restarts it. A handler is never switched off while the loop runs on: a loop
// that still iterates feeds the service watchdog, so a line without SYNC or without heartbeat
// supervision would look healthy. A flooded bus is read
// at most kFramesPerWake frames per wake-up, so timers (SYNC, heartbeat supervision) and posted
// work are never starved, and due timers also run between two frames of a burst (a SYNC is sent
// on time however many frames wait).

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "base/journal_event.hpp"
#include "base/log_rate.hpp"
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
  void on_frame(std::uint32_t cob_id, FrameHandler handler);       // 11-bit identifiers
  void on_extended_frame(std::uint32_t id, FrameHandler handler);  // 29-bit identifiers (PDOs so configured)
  void on_other_frame(FrameHandler handler);                       // RTR, error and unclaimed 29-bit frames
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
  static constexpr int kFramesPerWake = 64;  // one burst (kBurstFrames): timers wait for at most one
  // Within a burst, how often due timers are looked for between two frames: what a SYNC may wait
  // beyond its time while frames flood in (plus the frame being handled).
  static constexpr std::chrono::microseconds kTimerPollEvery{20};
  // A frame handler or timer that threw this many times in a row (a normal return starts the count
  // again) ends the loop through on_failure.
  static constexpr std::uint32_t kMaxHandlerFailures = 10;
  FlushId create_flush(Task callback);
  // Loop thread: runs the callback once after the frames being dispatched now; at once when called
  // outside frame dispatch. Requests before that run coalesce into one call.
  void request_flush(FlushId id);

  // Before start(): `on_readable` runs on the loop thread whenever `fd` (which the caller keeps
  // open) has something to read. Level-triggered: a callback that leaves data is called again.
  void watch(int fd, Task on_readable);

  // Any thread: runs the task on the loop thread, in posting order. For the bridge's own work,
  // which its callers bound (SDO kicks, one diagnostics snapshot a second, start-up). Posted on
  // the loop thread itself, it runs once the current wake-up's work is done, without a wake-up.
  void post(Task task);
  // Any thread: as post(), for what other applications ask for (service requests, set values,
  // commands), which arrives as fast as DDS delivers it. Refused while kMaxPosted tasks wait: the
  // task is dropped unrun, counted (posts_refused) and logged at a bounded rate, and the caller
  // answers the request itself. Keeps a request flood from growing memory without bound.
  static constexpr std::size_t kMaxPosted = 4096;
  [[nodiscard]] bool try_post(Task task);
  std::uint64_t posts_refused() const { return posts_refused_.load(std::memory_order_relaxed); }

  // Loop thread: transmits, counting and logging failures (the caller decides nothing on them).
  // Refused while transmission is held.
  Result<void> send(const can::CanFrame& frame);
  // Loop thread: a frame that stops a machine (an RPDO carrying a stop, an NMT stop): sent whether or
  // not transmission is held. A stop never waits for what the master believes about another
  // master; only the bus itself can refuse it.
  Result<void> send_stop(const can::CanFrame& frame);
  std::uint64_t stops_sent_while_held() const { return stops_sent_while_held_; }
  // Loop thread: a CiA 302-2 flying-master service (71h-76h), which no device acts on: sent whether
  // or not transmission is held, since a standby negotiates mastership before it has any.
  Result<void> send_negotiation(const can::CanFrame& frame);
  // Before start(): a loop whose wake-ups were more than `after` apart (its process was stopped or
  // starved, and another master may have taken the bus over meanwhile) transmits nothing but stops
  // and negotiation until it has read the frames that came meanwhile: what it would send now (a
  // SYNC's RPDOs) may no longer be what the bus's master says. What a frame handler sends in answer
  // to a frame goes. Zero: no guard.
  void guard_stalls(std::chrono::nanoseconds after) { stall_guard_ = after; }
  std::uint64_t stalls() const { return stalls_; }  // loop thread: wake-ups the guard held back
  // Loop thread: hold every transmission but stops (another master owns the bus) or release it.
  void hold_transmission(bool held) { held_ = held; }
  bool transmission_held() const { return held_; }
  std::uint64_t frames_held() const { return frames_held_; }  // refused while held

  // Before start(): called on the loop thread when the loop ends by a failure of its own (epoll, or
  // a frame handler or timer that threw kMaxHandlerFailures times in a row).
  void on_failure(std::function<void(const std::string& why)> handler) { failure_handler_ = std::move(handler); }

  // Before start(): how the loop's thread is scheduled. `name` is what ps and top -H show (the
  // kernel keeps 15 characters). realtime_priority 1..99 runs it SCHED_FIFO, so SYNC, the RPDOs and
  // heartbeat supervision run before any normal thread on the machine (DDS's among them); 0 is
  // normal scheduling. A priority the system refuses is logged and the loop runs at normal
  // priority: a line without realtime rights still runs.
  void set_thread(std::string name, int realtime_priority);
  // Before start(): the line and bus names its key events carry (base/journal_event: bus-off, and
  // error-active again after it).
  void name_events(journal::Where where) { where_ = std::move(where); }
  const journal::Where& where() const { return where_; }

  void start();
  void stop();  // idempotent; joins the thread
  bool on_loop_thread() const { return std::this_thread::get_id() == loop_thread_.load(std::memory_order_relaxed); }

  // Any thread: how many times the loop has woken up (epoll) so far. A service watchdog feeds
  // systemd only while this grows on every bus; arm a periodic timer so an idle loop still wakes.
  std::uint64_t iterations() const { return iterations_.load(std::memory_order_relaxed); }

  const can::Bus& bus() const { return *bus_; }
  can::BusStats stats() const { return bus_->stats(); }
  // Bits on the wire without stuffing, for the bus load (loop thread).
  std::uint64_t bits_in() const { return bits_in_; }
  std::uint64_t bits_out() const { return bits_out_; }
  // Callbacks that threw (loop thread).
  std::uint64_t handler_failures() const { return handler_failures_; }
  // Frames nobody on this bus handles (nodes the line does not have, identifiers no service uses).
  std::uint64_t frames_unclaimed() const { return frames_unclaimed_; }

  // The bus's own time, for what is judged by it (a heartbeat timeout): a timer that fires after
  // the loop was held up (the process stopped, a slow handler) fires before the frames that came
  // meanwhile are read, so it must not take the loop's clock for the bus's.
  // Loop thread: the newest timestamp (realtime ns, as the bus stamps frames) of a frame
  // dispatched so far; 0 before the first.
  std::int64_t last_frame_ns() const { return last_frame_ns_; }
  // Loop thread: frames may wait to be dispatched: a burst is being dispatched (a timer run
  // between two of its frames), one wake-up stopped at kFramesPerWake, or the bus has something
  // to read. False means every frame that reached this member so far was dispatched.
  bool input_pending() const;
  // Loop thread, outside frame dispatch: reads and dispatches the frames waiting on the bus now
  // (one wake-up's worth), so that a decision taken next on what the bus said (a stop refused as
  // "not heard") counts every frame that reached the bus before it. False when none waited, or
  // when called during dispatch (the frames then are being read).
  bool catch_up();
  // Frame handlers and timers that reached kMaxHandlerFailures: at most 1, and then the loop has
  // ended (kept for the diagnostics contract; nothing is switched off any more).
  std::uint64_t handlers_disabled() const { return handlers_disabled_; }

 private:
  struct Timer {
    int fd = -1;
    Task callback;
    std::uint32_t failures = 0;
  };
  struct Handler {
    FrameHandler fn;
    std::uint32_t failures = 0;
  };
  struct Watch {
    Task on_readable;
    std::uint32_t failures = 0;
  };

  void run();
  void schedule_thread();  // on the loop thread, before its first wait
  void loop();
  // The barrier: true when fn returned normally. `failures` (may be null: one-shot work) counts the
  // callback's throws in a row and is reset by a normal return; at kMaxHandlerFailures it throws
  // (std::runtime_error naming the callback) out of loop(), and run() reports it to on_failure.
  template <class Fn>
  bool guarded(Fn&& fn, std::uint32_t* failures, const char* what, std::uint32_t id);
  void call(Handler& h, const can::CanFrame& frame, const char* what);
  Result<void> transmit(const can::CanFrame& frame, const char* what);
  void watch_link();  // logs the bus's state changes and re-opens
  void drain_bus();
  void run_timer(TimerId id);
  void run_due_timers();  // between the frames of a burst
  void run_posted();
  void run_posted_here();  // what was posted on the loop thread, if anything
  void wake_for_posted();  // after a task joined posted_
  void dispatch(const can::CanFrame& frame);
  void run_flushes();

  std::unique_ptr<can::Bus> bus_;
  int epoll_fd_ = -1;
  int timers_fd_ = -1;  // epoll over the timers only: polled between frames
  int wake_fd_ = -1;    // eventfd: posted tasks and stop
  std::vector<std::unique_ptr<Timer>> timers_;
  std::vector<Watch> watches_;
  std::array<std::vector<Handler>, cob::kStandardIdCount> handlers_;
  std::vector<std::pair<std::uint32_t, Handler>> extended_handlers_;  // few: a linear scan
  std::vector<Handler> other_handlers_;
  struct Flush {
    Task callback;
    bool requested = false;
  };
  std::vector<Flush> flushes_;
  std::vector<FlushId> requested_flushes_;
  bool in_burst_ = false;
  bool posted_here_ = false;  // a task was posted on the loop thread: run before the next wait
  bool backlog_ = false;      // drain_bus() stopped at kFramesPerWake with frames possibly left
  bool held_ = false;
  std::chrono::nanoseconds stall_guard_{0};
  std::chrono::steady_clock::time_point last_wake_{};
  bool catching_up_ = false;       // a stall: the frames of meanwhile are read before anything is sent
  std::int64_t stall_end_ns_ = 0;  // realtime of the wake-up that ended the last stall
  bool in_handler_ = false;        // a frame is being dispatched to its handlers
  std::uint64_t stalls_ = 0;
  std::uint64_t frames_held_ = 0;
  std::uint64_t stops_sent_while_held_ = 0;
  std::uint64_t error_frames_logged_ = 0;
  std::uint64_t handler_failures_ = 0;
  std::uint64_t frames_unclaimed_ = 0;
  std::int64_t last_frame_ns_ = 0;
  can::BusState last_state_ = can::BusState::unknown;
  bool off_ = false;  // bus-off or down since it was last error-active
  journal::Where where_;
  std::uint64_t last_reopens_ = 0;
  std::uint64_t handlers_disabled_ = 0;
  std::function<void(const std::string&)> failure_handler_;
  std::string thread_name_;
  int realtime_priority_ = 0;
  std::uint64_t bits_in_ = 0;
  std::uint64_t bits_out_ = 0;

  std::mutex posted_mutex_;
  std::vector<Task> posted_;
  bool stopping_ = false;  // guarded by posted_mutex_
  LogRate refused_log_;    // guarded by posted_mutex_
  std::atomic<std::uint64_t> posts_refused_{0};
  std::atomic<std::uint64_t> iterations_{0};
  // Set by the loop thread first thing: other threads read it (post) while start() assigns thread_.
  std::atomic<std::thread::id> loop_thread_{};
  std::thread thread_;
};

}  // namespace lb::canopen
