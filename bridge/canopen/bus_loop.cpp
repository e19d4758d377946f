#include "canopen/bus_loop.hpp"

#include <fmt/ranges.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <spdlog/spdlog.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "can/detail.hpp"

namespace lb::canopen {
namespace {

// epoll user data: which source became ready.
constexpr std::uint64_t kBusTag = 0;
constexpr std::uint64_t kWakeTag = 1;
constexpr std::uint64_t kTimerTagBase = 2;
constexpr std::uint64_t kWatchTagBase = std::uint64_t{1} << 32;  // timers never number that many

void epoll_add(int epoll_fd, int fd, std::uint64_t tag) {
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.u64 = tag;
  if (::epoll_ctl(epoll_fd, EPOLL_CTL_ADD, fd, &ev) != 0) {
    throw std::runtime_error(std::string("epoll_ctl: ") + std::strerror(errno));
  }
}

// Classical CAN: 47 bits of overhead for a base frame (67 extended) plus the data, no stuffing.
std::uint64_t frame_bits(const can::CanFrame& f) { return (f.extended ? 67U : 47U) + 8U * (f.rtr ? 0U : f.len); }

timespec to_timespec(std::chrono::nanoseconds ns) {
  const auto s = std::chrono::duration_cast<std::chrono::seconds>(ns);
  return {static_cast<time_t>(s.count()), static_cast<long>((ns - s).count())};
}

}  // namespace

BusLoop::BusLoop(std::unique_ptr<can::Bus> bus) : bus_(std::move(bus)) {
  epoll_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  timers_fd_ = ::epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (epoll_fd_ < 0 || timers_fd_ < 0 || wake_fd_ < 0) throw std::runtime_error("cannot create bus loop descriptors");
  epoll_add(epoll_fd_, bus_->fd(), kBusTag);
  epoll_add(epoll_fd_, wake_fd_, kWakeTag);
}

BusLoop::~BusLoop() {
  stop();
  for (auto& t : timers_) ::close(t->fd);
  ::close(wake_fd_);
  ::close(timers_fd_);
  ::close(epoll_fd_);
}

void BusLoop::on_frame(std::uint32_t cob_id, FrameHandler handler) {
  if (cob_id >= cob::kStandardIdCount) throw std::invalid_argument("on_frame takes 11-bit identifiers");
  handlers_[cob_id].push_back({std::move(handler)});
}

void BusLoop::on_extended_frame(std::uint32_t id, FrameHandler handler) {
  extended_handlers_.emplace_back(id, Handler{std::move(handler)});
}

void BusLoop::on_other_frame(FrameHandler handler) { other_handlers_.push_back({std::move(handler)}); }

template <class Fn>
bool BusLoop::guarded(Fn&& fn, std::uint32_t* failures, const char* what, std::uint32_t id) {
  std::string error;
  try {
    fn();
    // Throws in a row, not in all: sporadic throws over months must not add up to a restart.
    if (failures != nullptr) *failures = 0;
    return true;
  } catch (const std::exception& e) {
    error = e.what();
  } catch (...) {
    error = "an exception that is not a std::exception";
  }
  ++handler_failures_;
  const std::uint32_t n = failures != nullptr ? ++*failures : 1;
  // Bounded: the first failures of each callback, then every 1000th of the loop's.
  if (n <= 3 || handler_failures_ % 1000 == 0) {
    spdlog::error("{}: the {} {:03X}h threw: {} ({} failures on this bus); the bus goes on", bus_->uri(), what, id,
                  error, handler_failures_);
  }
  if (failures != nullptr && n >= kMaxHandlerFailures) {
    // Switching it off would leave a loop that iterates (and so feeds the service watchdog) without
    // SYNC, heartbeat supervision or SDO answers: the loop ends instead, through run()'s failure
    // path, so the process exits and its service manager restarts it.
    ++handlers_disabled_;
    throw std::runtime_error(fmt::format("the {} {:03X}h threw {} times in a row (last: {})", what, id, n, error));
  }
  return false;
}

void BusLoop::call(Handler& h, const can::CanFrame& frame, const char* what) {
  guarded([&] { h.fn(frame); }, &h.failures, what, frame.id);
}

BusLoop::TimerId BusLoop::create_timer(Task callback) {
  const int fd = ::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
  if (fd < 0) throw std::runtime_error(std::string("timerfd_create: ") + std::strerror(errno));
  const TimerId id = timers_.size();
  timers_.push_back(std::make_unique<Timer>(Timer{fd, std::move(callback)}));
  epoll_add(epoll_fd_, fd, kTimerTagBase + id);
  epoll_add(timers_fd_, fd, kTimerTagBase + id);
  return id;
}

void BusLoop::arm_timer(TimerId id, std::chrono::nanoseconds first, std::chrono::nanoseconds period) {
  itimerspec spec{};
  // A zero it_value would disarm the timer; "now" means the next loop iteration.
  spec.it_value = to_timespec(std::max(first, std::chrono::nanoseconds{1}));
  spec.it_interval = to_timespec(period);
  ::timerfd_settime(timers_.at(id)->fd, 0, &spec, nullptr);
}

void BusLoop::disarm_timer(TimerId id) {
  itimerspec spec{};
  ::timerfd_settime(timers_.at(id)->fd, 0, &spec, nullptr);
}

void BusLoop::watch(int fd, Task on_readable) {
  epoll_add(epoll_fd_, fd, kWatchTagBase + watches_.size());
  watches_.push_back({std::move(on_readable), 0});
}

void BusLoop::wake_for_posted() {
  // The loop thread runs its own posts before it waits again (loop()): no system call for them.
  if (on_loop_thread()) {
    posted_here_ = true;
    return;
  }
  const std::uint64_t one = 1;
  [[maybe_unused]] auto n = ::write(wake_fd_, &one, sizeof one);
}

void BusLoop::post(Task task) {
  {
    std::lock_guard lock(posted_mutex_);
    posted_.push_back(std::move(task));
  }
  wake_for_posted();
}

bool BusLoop::try_post(Task task) {
  bool accepted = false, log = false;
  std::uint64_t held_back = 0;
  {
    std::lock_guard lock(posted_mutex_);
    accepted = posted_.size() < kMaxPosted;
    if (accepted) {
      posted_.push_back(std::move(task));
    } else {
      posts_refused_.fetch_add(1, std::memory_order_relaxed);
      log = refused_log_.allow();
      held_back = refused_log_.held_back();
    }
  }
  if (accepted) {
    wake_for_posted();
  } else if (log) {
    spdlog::warn("{}: {} requests already wait for the bus loop: request refused ({} refused in all){}", bus_->uri(),
                 kMaxPosted, posts_refused(), held_back == 0 ? "" : fmt::format(" ({} more not logged)", held_back));
  }
  return accepted;
}

Result<void> BusLoop::send(const can::CanFrame& frame) {
  if (held_) {
    ++frames_held_;
    return make_error(bus_->uri() + ": transmission held: another master is on this bus");
  }
  // What answers a frame just read (an SDO transfer's next step) is news, not stale: it goes.
  if (catching_up_ && !in_handler_) {
    if (input_pending()) {
      ++frames_held_;
      return make_error(bus_->uri() + ": the loop was stalled: the frames of meanwhile are read first");
    }
    catching_up_ = false;
  }
  return transmit(frame, "send");
}

// What every way out shares: the bus, the bits counted for the load, a failure logged.
Result<void> BusLoop::transmit(const can::CanFrame& frame, const char* what) {
  auto r = bus_->send(frame);
  if (r) bits_out_ += frame_bits(frame);
  if (!r) spdlog::debug("{}: {} {:03X} failed: {}", bus_->uri(), what, frame.id, r.error().message);
  return r;
}

Result<void> BusLoop::send_stop(const can::CanFrame& frame) {
  auto r = transmit(frame, "stop");
  if (r && held_) ++stops_sent_while_held_;
  return r;
}

Result<void> BusLoop::send_negotiation(const can::CanFrame& frame) {
  if (frame.id < cob::flying_master_first || frame.id > cob::flying_master_last || frame.extended)
    throw std::invalid_argument("send_negotiation sends the flying-master services 71h-76h only");
  return transmit(frame, "negotiation");
}

void BusLoop::set_thread(std::string name, int realtime_priority) {
  if (realtime_priority < 0 || realtime_priority > 99) throw std::invalid_argument("realtime priority must be 0..99");
  thread_name_ = std::move(name);
  realtime_priority_ = realtime_priority;
}

void BusLoop::schedule_thread() {
  if (!thread_name_.empty()) ::pthread_setname_np(::pthread_self(), thread_name_.substr(0, 15).c_str());
  if (realtime_priority_ == 0) return;
  sched_param param{};
  param.sched_priority = realtime_priority_;
  if (const int err = ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &param); err != 0) {
    spdlog::warn("{}: realtime priority {} (SCHED_FIFO) refused: {}; the bus loop runs at normal priority, so SYNC "
                 "and the RPDOs wait whenever other threads keep the CPU busy (grant CAP_SYS_NICE or an RLIMIT_RTPRIO "
                 "of at least {}: LimitRTPRIO= in a systemd unit)",
                 bus_->uri(), realtime_priority_, std::strerror(err), realtime_priority_);
    return;
  }
  spdlog::info("{}: the bus loop runs at realtime priority {} (SCHED_FIFO)", bus_->uri(), realtime_priority_);
}

void BusLoop::start() {
  if (thread_.joinable()) return;
  thread_ = std::thread([this] { run(); });
}

void BusLoop::stop() {
  {
    std::lock_guard lock(posted_mutex_);
    stopping_ = true;
  }
  const std::uint64_t one = 1;
  [[maybe_unused]] auto n = ::write(wake_fd_, &one, sizeof one);
  if (thread_.joinable() && !on_loop_thread()) thread_.join();
}

// The loop's own failures end it: a loop that cannot wait or read its descriptors any more must
// not look alive to a service manager.
void BusLoop::run() {
  loop_thread_.store(std::this_thread::get_id(), std::memory_order_relaxed);
  schedule_thread();
  std::string why;
  try {
    loop();
    return;
  } catch (const std::exception& e) {
    why = e.what();
  } catch (...) {
    why = "an exception that is not a std::exception";
  }
  spdlog::critical("{}: the bus loop failed and ended: {}", bus_->uri(), why);
  if (failure_handler_) failure_handler_(why);
}

void BusLoop::loop() {
  std::array<epoll_event, 16> events{};
  for (;;) {
    // Work posted on this thread runs first; what it posts in turn waits for the next round, so
    // the descriptors are still polled (without blocking) in between.
    run_posted_here();
    const int n = ::epoll_wait(epoll_fd_, events.data(), static_cast<int>(events.size()), posted_here_ ? 0 : -1);
    iterations_.fetch_add(1, std::memory_order_relaxed);
    if (stall_guard_.count() > 0) {
      const auto now = std::chrono::steady_clock::now();
      if (last_wake_ != std::chrono::steady_clock::time_point{} && now - last_wake_ > stall_guard_ && !catching_up_) {
        catching_up_ = true;
        stall_end_ns_ = can::detail::realtime_ns();
        ++stalls_;
      }
      last_wake_ = now;
    }
    if (n < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error(std::string("epoll_wait failed: ") + std::strerror(errno));
    }
    for (int i = 0; i < n; ++i) {
      const std::uint64_t tag = events[static_cast<std::size_t>(i)].data.u64;
      if (tag == kBusTag) {
        drain_bus();
      } else if (tag == kWakeTag) {
        std::uint64_t count = 0;
        [[maybe_unused]] auto r = ::read(wake_fd_, &count, sizeof count);
        {
          std::lock_guard lock(posted_mutex_);
          if (stopping_) return;
        }
        run_posted();
        if (backlog_) drain_bus();
      } else if (tag >= kWatchTagBase) {
        auto& w = watches_[tag - kWatchTagBase];
        guarded(w.on_readable, &w.failures, "watched descriptor", static_cast<std::uint32_t>(tag - kWatchTagBase));
        // What it posted (a set value's frame) goes out now, not after the round's other events.
        run_posted_here();
      } else {
        run_timer(tag - kTimerTagBase);
      }
    }
  }
}

void BusLoop::run_posted_here() {
  if (!posted_here_) return;
  posted_here_ = false;
  run_posted();
}

void BusLoop::run_timer(TimerId id) {
  auto& timer = *timers_[id];
  std::uint64_t expirations = 0;
  // Not due (any more): it already ran between the frames of a burst.
  if (::read(timer.fd, &expirations, sizeof expirations) != sizeof expirations) return;
  guarded([&timer] { timer.callback(); }, &timer.failures, "timer", static_cast<std::uint32_t>(id));
}

void BusLoop::run_due_timers() {
  std::array<epoll_event, 16> events{};
  const int n = ::epoll_wait(timers_fd_, events.data(), static_cast<int>(events.size()), 0);
  for (int i = 0; i < n; ++i) run_timer(events[static_cast<std::size_t>(i)].data.u64 - kTimerTagBase);
}

void BusLoop::drain_bus() {
  in_burst_ = true;
  backlog_ = false;
  auto next_timer_poll = std::chrono::steady_clock::time_point::min();
  for (int in_burst = 0, taken = 0;; ++in_burst, ++taken) {
    if (taken == kFramesPerWake) {
      // Back to epoll, so that due timers and posted work run; the wake-up brings the loop back
      // here even when the rest of the backlog is in the bus's batch buffer, not in the kernel.
      backlog_ = true;
      const std::uint64_t one = 1;
      [[maybe_unused]] auto n = ::write(wake_fd_, &one, sizeof one);
      break;
    }
    if (in_burst == kBurstFrames) {
      run_flushes();
      in_burst = 0;
    }
    // A due SYNC goes out between two frames, not after the burst: its period must not depend on
    // how many frames a flood brings. Polled every kTimerPollEvery, not every frame: the poll is a
    // system call, and a burst's frames take a few microseconds each.
    if (const auto now = std::chrono::steady_clock::now(); now >= next_timer_poll) {
      next_timer_poll = now + kTimerPollEvery;
      run_due_timers();
    }
    auto r = bus_->receive();
    if (!r) {
      spdlog::warn("{}: receive failed: {}", bus_->uri(), r.error().message);
      break;
    }
    if (!r->has_value()) break;
    if (!(*r)->error) bits_in_ += frame_bits(**r);
    dispatch(**r);
  }
  in_burst_ = false;
  run_flushes();
  watch_link();
}

// What the bus reports of its link (SocketCAN: down, deleted, re-opened; the controller's error
// states) is in the diagnostics; the log says when it changes, since that is when a line stops.
void BusLoop::watch_link() {
  const auto s = bus_->stats();
  if (s.reopens != last_reopens_) {
    spdlog::warn("{}: the interface is back and was opened again (re-open #{})", bus_->uri(), s.reopens);
    last_reopens_ = s.reopens;
  }
  if (s.state == last_state_) return;
  const auto level = s.state == can::BusState::down || s.state == can::BusState::bus_off ? spdlog::level::err
                     : s.state == can::BusState::error_active                            ? spdlog::level::info
                                                                                         : spdlog::level::warn;
  const auto state_text = [&] {
    return fmt::format("{}: controller state {} (was {})", bus_->uri(), can::to_string(s.state),
                       can::to_string(last_state_));
  };
  const std::initializer_list<journal::Field> fields{{journal::kBusState, std::string(can::to_string(s.state))},
                                                     {journal::kBusStateBefore,
                                                      std::string(can::to_string(last_state_))}};
  if (s.state == can::BusState::down) {
    off_ = true;
    journal::log(journal::Event::bus_off, level, where_,
                 fmt::format("{}: link down (interface down or gone): nothing is sent or received until it is back",
                             bus_->uri()),
                 fields);
  } else if (s.state == can::BusState::bus_off) {
    off_ = true;
    journal::log(journal::Event::bus_off, level, where_, state_text(), fields);
  } else if (s.state == can::BusState::error_active && off_) {
    off_ = false;
    journal::log(journal::Event::bus_back, level, where_, state_text(), fields);
  } else if (last_state_ != can::BusState::unknown || s.state != can::BusState::error_active) {
    spdlog::log(level, "{}", state_text());
  }
  last_state_ = s.state;
}

BusLoop::FlushId BusLoop::create_flush(Task callback) {
  flushes_.push_back(Flush{std::move(callback), false});
  return flushes_.size() - 1;
}

void BusLoop::request_flush(FlushId id) {
  auto& f = flushes_.at(id);
  if (!in_burst_) {
    guarded(f.callback, nullptr, "burst flush", static_cast<std::uint32_t>(id));
    return;
  }
  if (f.requested) return;
  f.requested = true;
  requested_flushes_.push_back(id);
}

void BusLoop::run_flushes() {
  // By index: a callback may request flushes (they join this round) but never creates one.
  for (std::size_t i = 0; i < requested_flushes_.size(); ++i) {  // NOLINT(modernize-loop-convert): it grows
    auto& f = flushes_[requested_flushes_[i]];
    f.requested = false;
    guarded(f.callback, nullptr, "burst flush", static_cast<std::uint32_t>(requested_flushes_[i]));
  }
  requested_flushes_.clear();
}

void BusLoop::run_posted() {
  std::vector<Task> batch;
  {
    std::lock_guard lock(posted_mutex_);
    batch.swap(posted_);
  }
  for (auto& task : batch) guarded(task, nullptr, "posted task", 0);
}

bool BusLoop::catch_up() {
  if (in_burst_ || !input_pending()) return false;
  drain_bus();
  return true;
}

bool BusLoop::input_pending() const {
  if (in_burst_ || backlog_) return true;
  pollfd p{bus_->fd(), POLLIN, 0};
  return ::poll(&p, 1, 0) > 0 && (p.revents & POLLIN) != 0;
}

void BusLoop::dispatch(const can::CanFrame& frame) {
  // Once per frame, not per handler: what the handlers send answers this frame (BusLoop::send).
  struct InHandler {
    bool& flag;
    explicit InHandler(bool& f) : flag(f) { flag = true; }
    ~InHandler() { flag = false; }
    InHandler(const InHandler&) = delete;
    InHandler& operator=(const InHandler&) = delete;
  } in_handler{in_handler_};
  last_frame_ns_ = std::max(last_frame_ns_, frame.timestamp_ns);
  // A frame stamped after the wake that ended the stall: every frame of meanwhile is read (a bus
  // delivers in order). Waiting for no input at all instead would hold the SYNC and heartbeat for
  // as long as the bus stays busy, and a standby takes a silent master's bus over.
  if (catching_up_ && frame.timestamp_ns >= stall_end_ns_) catching_up_ = false;
  if (!frame.extended && !frame.rtr && !frame.error && frame.id < cob::kStandardIdCount) {
    auto& handlers = handlers_[frame.id];
    if (handlers.empty()) ++frames_unclaimed_;
    for (auto& h : handlers) call(h, frame, "handler of frame");
    return;
  }
  if (frame.extended && !frame.rtr && !frame.error) {
    bool claimed = false;
    for (auto& [id, h] : extended_handlers_) {
      if (id == frame.id) {
        call(h, frame, "handler of 29-bit frame");
        claimed = true;
      }
    }
    if (claimed) return;
  }
  if (!frame.error) ++frames_unclaimed_;
  if (frame.error && error_frames_logged_++ % 100 == 0) {
    // Error class bits and data as <linux/can/error.h> defines them; counted in the bus stats.
    spdlog::warn("{}: error frame, class {:08X}h, data {:02X} ({} so far)", bus_->uri(), frame.id,
                 fmt::join(frame.payload(), " "), error_frames_logged_);
  }
  for (auto& h : other_handlers_) call(h, frame, "handler of other frame");
}

}  // namespace lb::canopen
