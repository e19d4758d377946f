#pragma once
// A kernel CAN interface (can0, vcan0, ...) through a raw SocketCAN socket.
//
// Faults: error frames (all classes enabled) come back as CanFrame{error = true} and drive
// BusStats::state (controller_state.hpp). When the interface goes down or is deleted, the socket
// is closed, the state becomes `down`, and the bus checks every 100 ms whether an interface of that
// name is up again; then it opens and binds a new socket (BusStats::reopens counts these), so a
// deleted and re-created interface works like one that was only taken down and up. Nothing above
// the bus has to act: sends fail (counted in tx_dropped) while the link is down and succeed again
// after, which is all a bus loop re-sending its PDO images at every SYNC needs.
//
// fd() is an epoll descriptor owned by the bus, holding the current socket and the retry timer. It
// never changes for the lifetime of the object, across any number of re-opens: register it once,
// level-triggered, and call receive() when it is readable (as VirtualBus).

#include <memory>
#include <string_view>

#include "can/bus.hpp"
#include "can/unique_fd.hpp"

struct can_frame;  // <linux/can.h>
struct msghdr;     // <sys/socket.h>

namespace lb::can {

class SocketCanBus final : public Bus {
  struct PrivateTag {
    explicit PrivateTag() = default;
  };

 public:
  // ifname as `ip link` shows it. Fails cleanly when the kernel has no SocketCAN (EAFNOSUPPORT),
  // when the interface does not exist or is not a CAN interface. An interface that exists but is
  // down is not an error: the bus starts in state `down` and opens the socket when it comes up.
  static Result<std::unique_ptr<SocketCanBus>> open(std::string_view ifname);
  // An interface name Linux accepts (1..15 characters, no '/', ':' or white space, not . or ..),
  // checked before anything is opened (the line configuration checks it too).
  static Result<void> check_name(std::string_view ifname);

  SocketCanBus(PrivateTag, std::string uri, std::string ifname, UniqueFd epoll, UniqueFd retry_timer);
  ~SocketCanBus() override;

  const std::string& uri() const override { return uri_; }
  int fd() const override { return epoll_.get(); }
  Result<std::optional<CanFrame>> receive() override;
  // Never waits: a full transmit queue (ENOBUFS/EAGAIN) drops the frame, counts it in tx_dropped
  // and tx_queue_full, and says so; so does a link that is down.
  Result<void> send(const CanFrame& frame) override;
  BusStats stats() const override { return stats_; }

 private:
  enum class Attach { attached, not_yet, failed };
  // Opens and binds a socket when the interface exists and is up.
  Attach attach(std::string* why);
  void link_lost();
  // One received frame and its ancillary data (timestamp, receive-queue drops) as a CanFrame.
  CanFrame decode(const ::can_frame& raw, ::msghdr& msg);
  void set_retry_timer(bool armed);

  std::string uri_;
  std::string ifname_;
  UniqueFd epoll_;
  UniqueFd retry_timer_;
  struct RxBatch;

  UniqueFd sock_;                // empty while the link is down
  std::unique_ptr<RxBatch> rx_;  // frames read by one recvmmsg, handed out one per receive()
  bool opened_once_ = false;
  std::uint32_t socket_dropped_ = 0;  // the current socket's SO_RXQ_OVFL count
  BusStats stats_;
};

}  // namespace lb::can
