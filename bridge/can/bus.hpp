#pragma once
// The one interface between CANopen and whatever carries the frames.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "base/result.hpp"
#include "can/can_frame.hpp"

namespace lb::can {

struct BusStats {
  std::uint64_t frames_in = 0;
  std::uint64_t frames_out = 0;
  std::uint64_t error_frames = 0;
  std::uint64_t tx_dropped = 0;  // frames the bus could not take (queue full, link down, refused)
};

enum class BusAccess { read_write, listen_only };

class Bus {
 public:
  virtual ~Bus() = default;
  Bus() = default;
  Bus(const Bus&) = delete;
  Bus& operator=(const Bus&) = delete;

  // The URI it was opened with, e.g. "socketcan:can0" or "virtual:demo".
  virtual const std::string& uri() const = 0;
  // A file descriptor that becomes readable (epoll) when receive() may return a frame.
  virtual int fd() const = 0;
  // Non-blocking: the next frame, std::nullopt when none is pending, an error when the bus failed.
  virtual Result<std::optional<CanFrame>> receive() = 0;
  // Non-blocking: queues the frame for transmission or says why it could not.
  virtual Result<void> send(const CanFrame& frame) = 0;
  virtual BusStats stats() const = 0;
};

// Opens "socketcan:<ifname>" or "virtual:<name>". listen_only returns a bus whose send() always
// fails without touching the medium (the monitor role).
Result<std::unique_ptr<Bus>> open_bus(std::string_view uri, BusAccess access = BusAccess::read_write);

}  // namespace lb::can
