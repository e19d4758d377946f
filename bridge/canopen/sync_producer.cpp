#include "canopen/sync_producer.hpp"

#include "can/detail.hpp"
#include "canopen/cob_id.hpp"

namespace lb::canopen {

SyncProducer::SyncProducer(BusLoop& loop, std::chrono::microseconds period) : loop_(loop), period_(period) {
  timer_ = loop_.create_timer([this] { tick(); });
}

void SyncProducer::start() {
  last_tick_ = {};
  loop_.arm_timer(timer_, period_, period_);
}

void SyncProducer::resume(std::chrono::nanoseconds first, std::function<void(std::int64_t)> sent) {
  first_sent_ = std::move(sent);
  last_tick_ = {};
  if (first < std::chrono::microseconds(1)) {
    tick();
    first = period_;
  }
  loop_.arm_timer(timer_, first, period_);
}

void SyncProducer::tick() {
  // Taken before the send: what the timer's lateness is, not how long the bus took to take it.
  const auto now = std::chrono::steady_clock::now();
  if (last_tick_ != std::chrono::steady_clock::time_point{}) {
    const auto off = std::chrono::duration<double>(now - last_tick_ - period_).count();
    deviations_.observe(off < 0 ? -off : off);
  }
  last_tick_ = now;
  can::CanFrame sync;
  sync.id = cob::sync;
  const auto ok = loop_.send(sync);  // a failed SYNC is counted by the bus; the next period tries again
  if (ok && first_sent_) {
    first_sent_(can::detail::realtime_ns());
    first_sent_ = nullptr;
  }
  for (const auto& s : subscribers_) s();
}

}  // namespace lb::canopen
