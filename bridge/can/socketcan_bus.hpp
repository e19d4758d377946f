#pragma once
// A kernel CAN interface (can0, vcan0, ...) through a raw SocketCAN socket.

#include <memory>
#include <string_view>

#include "can/bus.hpp"
#include "can/unique_fd.hpp"

namespace lb::can {

class SocketCanBus final : public Bus {
  struct PrivateTag {
    explicit PrivateTag() = default;
  };

 public:
  // ifname as `ip link` shows it. Fails cleanly when the kernel has no SocketCAN (EAFNOSUPPORT),
  // when the interface does not exist or is not a CAN interface.
  static Result<std::unique_ptr<SocketCanBus>> open(std::string_view ifname);

  SocketCanBus(PrivateTag, std::string uri, UniqueFd sock);

  const std::string& uri() const override { return uri_; }
  // The socket itself: stable for the lifetime of the object.
  int fd() const override { return sock_.get(); }
  // Error frames (all classes are enabled) come back as CanFrame{error = true}.
  Result<std::optional<CanFrame>> receive() override;
  // A full transmit queue (EAGAIN/ENOBUFS) drops the frame and says so; it never waits.
  Result<void> send(const CanFrame& frame) override;
  BusStats stats() const override { return stats_; }

 private:
  std::string uri_;
  UniqueFd sock_;
  BusStats stats_;
};

}  // namespace lb::can
