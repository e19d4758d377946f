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

// Controller state as error frames and the link report it (virtual buses stay error_active).
enum class BusState { unknown, error_active, error_warning, error_passive, bus_off, down };

constexpr std::string_view to_string(BusState s) {
  switch (s) {
    case BusState::error_active: return "error-active";
    case BusState::error_warning: return "error-warning";
    case BusState::error_passive: return "error-passive";
    case BusState::bus_off: return "bus-off";
    case BusState::down: return "down";
    case BusState::unknown: break;
  }
  return "unknown";
}

struct BusStats {
  std::uint64_t frames_in = 0;
  std::uint64_t frames_out = 0;
  std::uint64_t error_frames = 0;
  std::uint64_t tx_dropped = 0;  // frames the bus could not take (queue full, link down, refused)
  BusState state = BusState::unknown;
  // Faults, as the controller, the socket and the link report them (SocketCAN; a replayed log
  // reports the recorded ones). Each counter only grows.
  std::uint64_t tx_queue_full = 0;  // part of tx_dropped: transmit queue full (ENOBUFS/EAGAIN)
  std::uint64_t rx_dropped = 0;     // frames the socket's receive queue had no room for
  std::uint64_t rx_overflows = 0;   // controller RX/TX overflow reports (error frames)
  std::uint64_t bus_offs = 0;       // entries into bus-off
  std::uint64_t reopens = 0;        // times the interface came back and was opened again
  std::uint64_t record_errors = 0;  // frames a recording (record:) could not write
  // The controller's error counters from the last error frame that carried them (CAN_ERR_CNT).
  std::uint8_t tx_error_counter = 0;
  std::uint8_t rx_error_counter = 0;
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

// Whether a bus URI can be opened as far as its text goes (scheme, name rules, a log: spec),
// without opening anything: the line configuration refuses a bad one with its file:line:column.
Result<void> check_bus_uri(std::string_view uri);

// Opens "socketcan:<ifname>" or "virtual:<name>". listen_only returns a bus whose send() always
// fails without touching the medium (the monitor role).
Result<std::unique_ptr<Bus>> open_bus(std::string_view uri, BusAccess access = BusAccess::read_write);

}  // namespace lb::can
