#include "can/socketcan_bus.hpp"

#include <algorithm>
#include <cctype>

#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <net/if_arp.h>
#include <sys/epoll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/timerfd.h>

#include <array>
#include <cerrno>
#include <cstring>

#include "can/controller_state.hpp"
#include "can/detail.hpp"

namespace lb::can {

using detail::errno_text;

namespace {

// Fast enough that a line notices a link back within a couple of SYNC periods, cheap when idle.
constexpr long kLinkRetryIntervalNs = 100'000'000;

bool link_error(int err) { return err == ENETDOWN || err == ENODEV || err == ENXIO; }

}  // namespace

Result<void> SocketCanBus::check_name(std::string_view ifname) {
  const auto bad = [](char c) { return c == '/' || c == ':' || std::isspace(static_cast<unsigned char>(c)) != 0; };
  if (ifname.empty() || ifname.size() >= IFNAMSIZ || ifname == "." || ifname == ".." ||
      std::any_of(ifname.begin(), ifname.end(), bad)) {
    return make_error("socketcan:" + std::string(ifname.substr(0, 100)) + ": an interface name is 1 to " +
                      std::to_string(IFNAMSIZ - 1) + " characters, without '/', ':' or white space");
  }
  return {};
}

Result<std::unique_ptr<SocketCanBus>> SocketCanBus::open(std::string_view ifname) {
  std::string uri = "socketcan:" + std::string(ifname);
  if (auto ok = check_name(ifname); !ok) return ok.error();
  UniqueFd epoll{::epoll_create1(EPOLL_CLOEXEC)};
  UniqueFd timer{::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC)};
  if (!epoll || !timer || !detail::epoll_add(epoll.get(), timer.get())) {
    return make_error(uri + ": cannot create descriptors: " + errno_text(errno));
  }
  auto bus = std::make_unique<SocketCanBus>(PrivateTag{}, std::move(uri), std::string(ifname), std::move(epoll),
                                            std::move(timer));
  std::string why;
  switch (bus->attach(&why)) {
    case Attach::attached: break;
    case Attach::not_yet:  // exists, but down: wait for it
      bus->stats_.state = BusState::down;
      bus->set_retry_timer(true);
      break;
    case Attach::failed: return make_error(why);
  }
  return bus;
}

SocketCanBus::~SocketCanBus() = default;

SocketCanBus::Attach SocketCanBus::attach(std::string* why) {
  UniqueFd sock{::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW)};
  if (!sock) {
    const int err = errno;
    if (err == EAFNOSUPPORT) {
      *why = uri_ + ": this kernel has no SocketCAN support (socket(PF_CAN) failed: " + errno_text(err) +
             "); load the can and can-raw modules or use a virtual: bus";
    } else {
      *why = uri_ + ": cannot create a CAN socket: " + errno_text(err);
    }
    return Attach::failed;
  }
  const unsigned index = ::if_nametoindex(ifname_.c_str());
  if (index == 0) {
    *why = uri_ + ": no network interface named '" + ifname_ + "': " + errno_text(errno);
    return opened_once_ ? Attach::not_yet : Attach::failed;  // deleted: it may be re-created
  }
  ifreq ifr{};
  std::memcpy(ifr.ifr_name, ifname_.c_str(), ifname_.size());
  if (::ioctl(sock.get(), SIOCGIFHWADDR, &ifr) == 0 && ifr.ifr_hwaddr.sa_family != ARPHRD_CAN) {
    *why = uri_ + ": '" + ifname_ + "' is not a CAN interface";
    return Attach::failed;
  }
  if (::ioctl(sock.get(), SIOCGIFFLAGS, &ifr) == 0 && (ifr.ifr_flags & IFF_UP) == 0) {
    *why = uri_ + ": the interface is down";
    return Attach::not_yet;
  }

  // Without this filter the kernel drops error frames, and bus-off or overruns would go unseen.
  const can_err_mask_t err_mask = CAN_ERR_MASK;
  const int on = 1;
  if (::setsockopt(sock.get(), SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) != 0 ||
      // The kernel's reception time is closer to the wire than a clock read after scheduling delays.
      ::setsockopt(sock.get(), SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0 ||
      // Frames the receive queue had no room for: counted by the kernel, reported with each frame.
      ::setsockopt(sock.get(), SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0) {
    *why = uri_ + ": cannot set socket options: " + errno_text(errno);
    return Attach::failed;
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(index);
  if (::bind(sock.get(), reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int err = errno;
    *why = uri_ + ": cannot bind to '" + ifname_ + "'" + (err == ENODEV ? " (not a CAN interface)" : "") + ": " +
           errno_text(err);
    // Gone between the look-up and bind: just not yet. A non-CAN interface at start: a real error.
    return opened_once_ && link_error(err) ? Attach::not_yet : Attach::failed;
  }
  if (!detail::epoll_add(epoll_.get(), sock.get())) {
    *why = uri_ + ": epoll_ctl failed: " + errno_text(errno);
    return Attach::failed;
  }
  sock_ = std::move(sock);
  socket_dropped_ = 0;
  if (opened_once_) ++stats_.reopens;
  opened_once_ = true;
  // No error frame since the link came up: the controller starts error-active.
  stats_.state = BusState::error_active;
  set_retry_timer(false);
  return Attach::attached;
}

void SocketCanBus::link_lost() {
  if (sock_) ::epoll_ctl(epoll_.get(), EPOLL_CTL_DEL, sock_.get(), nullptr);
  sock_.reset();
  stats_.state = BusState::down;
  std::string why;
  if (attach(&why) != Attach::attached) set_retry_timer(true);  // back already (a quick down/up)?
}

void SocketCanBus::set_retry_timer(bool armed) {
  itimerspec spec{};
  if (armed) {
    spec.it_value.tv_nsec = kLinkRetryIntervalNs;
    spec.it_interval.tv_nsec = kLinkRetryIntervalNs;
  }
  ::timerfd_settime(retry_timer_.get(), 0, &spec, nullptr);  // also clears a pending expiry
}

// One system call fetches up to kSize pending frames with their ancillary data: at 8000 frames/s
// a recvmsg per frame is most of what taking a frame costs.
struct SocketCanBus::RxBatch {
  static constexpr unsigned kSize = 32;
  static constexpr std::size_t kControl = CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t));
  std::array<can_frame, kSize> raw{};
  std::array<iovec, kSize> iov{};
  std::array<mmsghdr, kSize> hdr{};
  alignas(cmsghdr) std::array<std::array<unsigned char, kControl>, kSize> control{};
  unsigned count = 0;  // frames in raw
  unsigned next = 0;   // the next one to hand out

  // recvmmsg writes msg_controllen back: every call starts from full-size buffers.
  void arm() {
    for (unsigned i = 0; i < kSize; ++i) {
      iov[i] = {&raw[i], sizeof(can_frame)};
      hdr[i] = {};
      hdr[i].msg_hdr.msg_iov = &iov[i];
      hdr[i].msg_hdr.msg_iovlen = 1;
      hdr[i].msg_hdr.msg_control = control[i].data();
      hdr[i].msg_hdr.msg_controllen = kControl;
    }
    count = next = 0;
  }
};

SocketCanBus::SocketCanBus(PrivateTag, std::string uri, std::string ifname, UniqueFd epoll, UniqueFd retry_timer)
    : uri_(std::move(uri)),
      ifname_(std::move(ifname)),
      epoll_(std::move(epoll)),
      retry_timer_(std::move(retry_timer)),
      rx_(std::make_unique<RxBatch>()) {}

Result<std::optional<CanFrame>> SocketCanBus::receive() {
  for (;;) {
    while (rx_->next < rx_->count) {
      const unsigned i = rx_->next++;
      // CAN FD frames are not enabled on this socket, so anything but a classical frame is noise.
      if (rx_->hdr[i].msg_len != sizeof(can_frame)) continue;
      return std::optional<CanFrame>{decode(rx_->raw[i], rx_->hdr[i].msg_hdr)};
    }
    if (!sock_) {
      std::uint64_t expirations = 0;
      [[maybe_unused]] const auto n = ::read(retry_timer_.get(), &expirations, sizeof expirations);
      std::string why;
      if (attach(&why) == Attach::failed) return make_error(why);
      if (!sock_) return std::optional<CanFrame>{};
    }
    rx_->arm();
    const int n = ::recvmmsg(sock_.get(), rx_->hdr.data(), RxBatch::kSize, MSG_DONTWAIT, nullptr);
    if (n > 0) {
      rx_->count = static_cast<unsigned>(n);
      continue;
    }
    const int err = n < 0 ? errno : EIO;
    if (err == EAGAIN || err == EWOULDBLOCK) return std::optional<CanFrame>{};
    if (err == EINTR) continue;
    if (link_error(err)) {
      link_lost();
      return std::optional<CanFrame>{};
    }
    return make_error(uri_ + ": receive failed: " + errno_text(err));
  }
}

CanFrame SocketCanBus::decode(const can_frame& raw, msghdr& msg) {
  CanFrame frame;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS) {
      timespec ts{};
      std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
      frame.timestamp_ns = std::int64_t{ts.tv_sec} * 1'000'000'000 + ts.tv_nsec;
    } else if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
      std::uint32_t dropped = 0;  // since the socket was opened
      std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
      if (dropped > socket_dropped_) {
        stats_.rx_dropped += dropped - socket_dropped_;
        socket_dropped_ = dropped;
      }
    }
  }
  if (frame.timestamp_ns == 0) frame.timestamp_ns = detail::realtime_ns();

  if ((raw.can_id & CAN_ERR_FLAG) != 0) {
    frame.error = true;
    frame.id = raw.can_id & CAN_ERR_MASK;
    frame.len = CAN_ERR_DLC;
    std::memcpy(frame.data.data(), raw.data, CAN_ERR_DLC);
    ++stats_.error_frames;
    apply_error_frame(frame, stats_);
  } else {
    frame.extended = (raw.can_id & CAN_EFF_FLAG) != 0;
    frame.rtr = (raw.can_id & CAN_RTR_FLAG) != 0;
    frame.id = raw.can_id & (frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
    frame.len = raw.len > CAN_MAX_DLEN ? CAN_MAX_DLEN : raw.len;
    std::memcpy(frame.data.data(), raw.data, frame.len);
    ++stats_.frames_in;
  }
  return frame;
}

Result<void> SocketCanBus::send(const CanFrame& frame) {
  if (auto ok = detail::check_sendable(frame, uri_); !ok) return ok;
  if (frame.error) return make_error(uri_ + ": error frames cannot be transmitted");
  if (!sock_) {
    ++stats_.tx_dropped;
    return make_error(uri_ + ": link down, frame dropped");
  }

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
    // Never retried here: the caller's next period (SYNC) brings the current image again.
    if (err == EAGAIN || err == EWOULDBLOCK || err == ENOBUFS) {
      ++stats_.tx_queue_full;
      return make_error(uri_ + ": transmit queue full, frame dropped");
    }
    if (link_error(err)) {
      link_lost();
      return make_error(uri_ + ": link down, frame dropped");
    }
    return make_error(uri_ + ": transmit failed: " + errno_text(err));
  }
}

}  // namespace lb::can
