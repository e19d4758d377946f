#pragma once
// The monitor role: a bus that receives everything and can never transmit, whatever the layers
// above it try. Refusal happens here, below all protocol logic, so no code path can leak a frame.

#include <memory>

#include "can/bus.hpp"

namespace lb::can {

class ListenOnlyBus final : public Bus {
 public:
  // inner must not be null (a programming error: throws std::invalid_argument).
  explicit ListenOnlyBus(std::unique_ptr<Bus> inner);

  const std::string& uri() const override { return inner_->uri(); }
  int fd() const override { return inner_->fd(); }
  Result<std::optional<CanFrame>> receive() override { return inner_->receive(); }
  // Always fails and counts the frame in tx_dropped; the inner bus is never touched.
  Result<void> send(const CanFrame& frame) override;
  BusStats stats() const override;

 private:
  std::unique_ptr<Bus> inner_;
  std::uint64_t refused_ = 0;
};

}  // namespace lb::can
