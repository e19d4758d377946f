#include "can/listen_only_bus.hpp"

#include <stdexcept>

namespace lb::can {

ListenOnlyBus::ListenOnlyBus(std::unique_ptr<Bus> inner) : inner_(std::move(inner)) {
  if (!inner_) throw std::invalid_argument("ListenOnlyBus needs a bus to wrap");
}

Result<void> ListenOnlyBus::send(const CanFrame& /*frame*/) {
  ++refused_;
  return make_error("bus " + inner_->uri() + " is listen-only (monitor role): transmission refused");
}

BusStats ListenOnlyBus::stats() const {
  BusStats s = inner_->stats();
  s.tx_dropped += refused_;
  return s;
}

}  // namespace lb::can
