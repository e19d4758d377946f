#include "canopen/sync_producer.hpp"

#include "can/detail.hpp"
#include "canopen/cob_id.hpp"

namespace lb::canopen {

SyncProducer::SyncProducer(BusLoop& loop, std::chrono::microseconds period) : loop_(loop), period_(period) {
  timer_ = loop_.create_timer([this] { tick(); });
}

void SyncProducer::start() { loop_.arm_timer(timer_, period_, period_); }

void SyncProducer::resume(std::chrono::nanoseconds first, std::function<void(std::int64_t)> sent) {
  first_sent_ = std::move(sent);
  if (first < std::chrono::microseconds(1)) {
    tick();
    first = period_;
  }
  loop_.arm_timer(timer_, first, period_);
}

void SyncProducer::tick() {
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
