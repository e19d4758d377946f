#include "can/socketcan_bus.hpp"

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>

#include <cerrno>
#include <cstring>

#include "can/detail.hpp"

namespace lb::can {

using detail::errno_text;

Result<std::unique_ptr<SocketCanBus>> SocketCanBus::open(std::string_view ifname) {
  std::string uri = "socketcan:" + std::string(ifname);
  if (ifname.empty() || ifname.size() >= IFNAMSIZ) {
    return make_error(uri + ": interface name must be 1 to " + std::to_string(IFNAMSIZ - 1) +
                      " characters");
  }

  UniqueFd sock{::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW)};
  if (!sock) {
    const int err = errno;
    if (err == EAFNOSUPPORT) {
      return make_error(uri + ": this kernel has no SocketCAN support (socket(PF_CAN) failed: " +
                        errno_text(err) +
                        "); load the can and can-raw modules or use a virtual: bus");
    }
    return make_error(uri + ": cannot create a CAN socket: " + errno_text(err));
  }

  const std::string name(ifname);
  const unsigned index = ::if_nametoindex(name.c_str());
  if (index == 0) {
    return make_error(uri + ": no network interface named '" + name + "': " + errno_text(errno));
  }

  // Without this filter the kernel drops error frames, and bus-off or overruns would go unseen.
  const can_err_mask_t err_mask = CAN_ERR_MASK;
  if (::setsockopt(sock.get(), SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) != 0) {
    return make_error(uri + ": cannot enable error frames: " + errno_text(errno));
  }
  // The kernel's reception time is closer to the wire than a clock read after scheduling delays.
  const int on = 1;
  if (::setsockopt(sock.get(), SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0) {
    return make_error(uri + ": cannot enable receive timestamps: " + errno_text(errno));
  }

  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(index);
  if (::bind(sock.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    return make_error(uri + ": cannot bind to '" + name + "'" +
                      (err == ENODEV ? " (not a CAN interface)" : "") + ": " + errno_text(err));
  }
  return std::make_unique<SocketCanBus>(PrivateTag{}, std::move(uri), std::move(sock));
}

SocketCanBus::SocketCanBus(PrivateTag, std::string uri, UniqueFd sock)
    : uri_(std::move(uri)), sock_(std::move(sock)) {}

Result<std::optional<CanFrame>> SocketCanBus::receive() {
  for (;;) {
    can_frame raw{};
    iovec iov{&raw, sizeof raw};
    alignas(cmsghdr) unsigned char control[CMSG_SPACE(sizeof(timespec))];
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;

    const ssize_t n = ::recvmsg(sock_.get(), &msg, MSG_DONTWAIT);
    if (n < 0) {
      const int err = errno;
      if (err == EAGAIN || err == EWOULDBLOCK) return std::optional<CanFrame>{};
      if (err == EINTR) continue;
      return make_error(uri_ + ": receive failed: " + errno_text(err));
    }
    // CAN FD frames are not enabled on this socket, so anything but a classical frame is noise.
    if (static_cast<std::size_t>(n) != sizeof raw) continue;

    CanFrame frame;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
        timespec ts{};
        std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
        frame.timestamp_ns = std::int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
      }
    }
    if (frame.timestamp_ns == 0) frame.timestamp_ns = detail::realtime_ns();

    if ((raw.can_id & CAN_ERR_FLAG) != 0) {
      frame.error = true;
      frame.id = raw.can_id & CAN_ERR_MASK;
      frame.len = CAN_ERR_DLC;
      std::memcpy(frame.data.data(), raw.data, CAN_ERR_DLC);
      ++stats_.error_frames;
    } else {
      frame.extended = (raw.can_id & CAN_EFF_FLAG) != 0;
      frame.rtr = (raw.can_id & CAN_RTR_FLAG) != 0;
      frame.id = raw.can_id & (frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
      frame.len = raw.len > CAN_MAX_DLEN ? CAN_MAX_DLEN : raw.len;
      std::memcpy(frame.data.data(), raw.data, frame.len);
      ++stats_.frames_in;
    }
    return std::optional<CanFrame>{frame};
  }
}

Result<void> SocketCanBus::send(const CanFrame& frame) {
  if (auto ok = detail::check_sendable(frame, uri_); !ok) return ok;
  if (frame.error) return make_error(uri_ + ": error frames cannot be transmitted");

  can_frame raw{};
  raw.can_id = frame.id | (frame.extended ? CAN_EFF_FLAG : 0u) | (frame.rtr ? CAN_RTR_FLAG : 0u);
  raw.len = frame.len;
  std::memcpy(raw.data, frame.data.data(), frame.len);

  for (;;) {
    const ssize_t n = ::send(sock_.get(), &raw, sizeof raw, MSG_DONTWAIT | MSG_NOSIGNAL);
    if (n == static_cast<ssize_t>(sizeof raw)) {
      ++stats_.frames_out;
      return {};
    }
    const int err = n < 0 ? errno : EIO;
    if (err == EINTR) continue;
    ++stats_.tx_dropped;
    // ENOBUFS is how SocketCAN reports a full qdisc/controller queue: congestion, not a failure.
    if (err == EAGAIN || err == EWOULDBLOCK || err == ENOBUFS) {
      return make_error(uri_ + ": transmit queue full, frame dropped");
    }
    return make_error(uri_ + ": transmit failed: " + errno_text(err));
  }
}

}  // namespace lb::can
