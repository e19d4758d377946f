#include "canopen/cycle_deadline.hpp"

#include <algorithm>

namespace lb::canopen {

namespace {
// An interval outside these is no SYNC period (a master restarted, a stall): the configured one is
// used instead. CiA 301 1006h allows 1 us .. 4295 s; a line runs 1 ms .. 1 s.
constexpr std::chrono::nanoseconds kShortest = std::chrono::microseconds(200);
constexpr std::chrono::nanoseconds kLongest = std::chrono::seconds(10);
}  // namespace

CycleDeadline::CycleDeadline(BusLoop& loop, std::chrono::microseconds configured_period)
    : loop_(loop), interval_(std::clamp<std::chrono::nanoseconds>(configured_period, kShortest, kLongest)) {
  timer_ = loop_.create_timer([this] { close(); });
}

CycleDeadline::WaiterId CycleDeadline::create_waiter(BusLoop::Task on_deadline) {
  waiters_.push_back(Waiter{std::move(on_deadline), false});
  return waiters_.size() - 1;
}

void CycleDeadline::seen() {
  close();  // what waited for the cycle before goes now, before this cycle's PDOs arrive
  const auto now = std::chrono::steady_clock::now();
  if (last_sync_ != std::chrono::steady_clock::time_point{}) {
    const auto interval = now - last_sync_;
    if (interval >= kShortest && interval <= kLongest) interval_ = interval;
  }
  last_sync_ = now;
  open_ = true;
  loop_.arm_timer(timer_, deadline());
}

void CycleDeadline::wait(WaiterId id) {
  auto& w = waiters_.at(id);
  if (w.waiting) return;
  w.waiting = true;
  waiting_.push_back(id);
}

void CycleDeadline::close() {
  open_ = false;
  // By index: a callback may ask to wait again (it joins this round).
  for (std::size_t i = 0; i < waiting_.size(); ++i) {  // NOLINT(modernize-loop-convert): it grows
    auto& w = waiters_[waiting_[i]];
    w.waiting = false;
    w.callback();
  }
  waiting_.clear();
}

}  // namespace lb::canopen
