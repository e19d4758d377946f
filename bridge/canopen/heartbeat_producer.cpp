#include "canopen/heartbeat_producer.hpp"

#include "canopen/nmt.hpp"

namespace lb::canopen {

HeartbeatProducer::HeartbeatProducer(BusLoop& loop, std::uint8_t node_id, std::chrono::milliseconds period)
    : loop_(loop), node_id_(node_id), period_(period) {
  timer_ = loop_.create_timer([this] { (void)loop_.send(make_heartbeat(node_id_, NmtState::operational)); });
}

void HeartbeatProducer::start() {
  (void)loop_.send(make_heartbeat(node_id_, NmtState::boot_up));  // the master boots too
  loop_.arm_timer(timer_, period_, period_);
}

void HeartbeatProducer::resume() {
  (void)loop_.send(make_heartbeat(node_id_, NmtState::operational));
  loop_.arm_timer(timer_, period_, period_);
}

}  // namespace lb::canopen
