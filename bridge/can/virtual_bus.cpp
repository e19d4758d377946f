#include "can/virtual_bus.hpp"

#include <linux/can/error.h>
#include <poll.h>
#include <pthread.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/timerfd.h>
#include <sys/un.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <system_error>
#include <thread>
#include <type_traits>
#include <vector>

#include "can/detail.hpp"
#include "can/virtual_bus_wire.hpp"

namespace lb::can {

using detail::errno_text;

namespace {

constexpr std::string_view kAddressPrefix = "linebridge-vbus/";
constexpr std::size_t kMaxNameLen = sizeof(sockaddr_un::sun_path) - 1 - kAddressPrefix.size();
// Asked of the kernel for every connection; it grants min(this, net.core.wmem_max) * 2. A queued
// message costs ~768 bytes of it, so a member can fall behind by ~2700 frames (~550 with Debian's
// default wmem_max of 208 KiB): 70 to 340 ms of a saturated 1 Mbit/s bus before it loses any.
constexpr int kSocketBuffer = 1 << 20;
constexpr auto kOpenTimeout = std::chrono::seconds(2);
constexpr auto kJoinRetryPause = std::chrono::milliseconds(2);
constexpr long kHubRetryIntervalNs = 10'000'000;
// Messages read from one member before the hub looks at the others again (fairness, not order).
constexpr int kPumpBatch = 64;

using WireMsg = wire::Msg;
using wire::Kind;
constexpr ssize_t kMsgSize = sizeof(WireMsg);

// What a member gets in place of the frames the hub had to drop for it.
WireMsg overflow_notice() {
  WireMsg m{};
  m.id = CAN_ERR_CRTL;
  m.kind = Kind::frame;
  m.flags = wire::kFlagError;
  m.len = CAN_ERR_DLC;
  m.data[1] = CAN_ERR_CRTL_RX_OVERFLOW;
  return m;
}

bool valid_name(std::string_view name) {
  if (name.empty() || name.size() > kMaxNameLen) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

struct UnixAddress {
  sockaddr_un addr{};
  socklen_t len = 0;
  const sockaddr* get() const { return reinterpret_cast<const sockaddr*>(&addr); }
};

UnixAddress unix_address(const std::string& abstract_name) {
  UnixAddress a;
  a.addr.sun_family = AF_UNIX;
  std::memcpy(a.addr.sun_path, abstract_name.data(), abstract_name.size());
  a.len = static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + abstract_name.size());
  return a;
}

UniqueFd seqpacket_socket() {
  UniqueFd s{::socket(AF_UNIX, SOCK_SEQPACKET | SOCK_NONBLOCK | SOCK_CLOEXEC, 0)};
  if (s) {
    // Best effort: the kernel clamps the value, and a smaller buffer only means earlier drops.
    ::setsockopt(s.get(), SOL_SOCKET, SO_SNDBUF, &kSocketBuffer, sizeof kSocketBuffer);
  }
  return s;
}

// Messages for one recvmmsg or sendmmsg, with the headers that point into them: a member reads
// its frames this way, and the hub reads and forwards them, so that at full load neither makes a
// system call per frame.
struct WireBatch {
  static constexpr unsigned kSize = 32;
  std::array<WireMsg, kSize> msgs{};
  std::array<iovec, kSize> iov{};
  std::array<mmsghdr, kSize> hdr{};
  WireBatch() {
    for (unsigned i = 0; i < kSize; ++i) {
      iov[i] = {&msgs[i], sizeof(WireMsg)};
      hdr[i].msg_hdr.msg_iov = &iov[i];
      hdr[i].msg_hdr.msg_iovlen = 1;
    }
  }
};

}  // namespace

// -------------------------------------------------------------------------------------------------
// The hub: one thread, one epoll over the listening socket and the member connections. Reading
// and forwarding one message at a time on a single thread is what makes the order total.

class VirtualBus::Hub {
 public:
  static Result<std::unique_ptr<Hub>> start(UniqueFd listener, const std::string& uri) {
    UniqueFd epoll{::epoll_create1(EPOLL_CLOEXEC)};
    UniqueFd wake{::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC)};
    if (!epoll || !wake || !detail::epoll_add(epoll.get(), listener.get()) ||
        !detail::epoll_add(epoll.get(), wake.get())) {
      return make_error(uri + ": cannot set up the hub: " + errno_text(errno));
    }
    try {
      return std::make_unique<Hub>(std::move(listener), std::move(epoll), std::move(wake));
    } catch (const std::system_error& e) {  // thread creation: resource exhaustion, not a bug
      return make_error(uri + ": cannot start the hub thread: " + e.what());
    }
  }

  Hub(UniqueFd listener, UniqueFd epoll, UniqueFd wake)
      : listener_(std::move(listener)), epoll_(std::move(epoll)), wake_(std::move(wake)), thread_([this] { run(); }) {
    ::pthread_setname_np(thread_.native_handle(), "lb-vbus-hub");
  }

  ~Hub() {
    const std::uint64_t one = 1;
    [[maybe_unused]] const auto n = ::write(wake_.get(), &one, sizeof one);
    thread_.join();
  }

  Hub(const Hub&) = delete;
  Hub& operator=(const Hub&) = delete;

  bool running() const { return running_.load(std::memory_order_relaxed); }

 private:
  struct Member {
    UniqueFd fd;
    bool overflowed = false;  // frames were dropped for it since the last one delivered
    bool gone = false;
  };

  void run() {
    epoll_event events[16];
    for (bool stop = false; !stop;) {
      const int n = ::epoll_wait(epoll_.get(), events, static_cast<int>(std::size(events)), -1);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) break;
      for (int i = 0; i < n && !stop; ++i) {
        const int fd = events[i].data.fd;
        if (fd == wake_.get()) {
          stop = true;
        } else if (fd == listener_.get()) {
          stop = !accept_members();
        } else {
          pump(fd);
        }
      }
      sweep();
    }
    // Release the address first, so members that see their connection close can bind it at once.
    listener_.reset();
    members_.clear();
    running_.store(false, std::memory_order_relaxed);
  }

  // False when the listening socket failed for good: the hub then shuts down and the members elect
  // another, which beats a hub that nobody new can join (or a thread spinning on EMFILE).
  bool accept_members() {
    for (;;) {
      UniqueFd fd{::accept4(listener_.get(), nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC)};
      if (!fd) {
        const int err = errno;
        if (err == EINTR || err == ECONNABORTED) continue;
        return err == EAGAIN || err == EWOULDBLOCK;
      }
      ::setsockopt(fd.get(), SOL_SOCKET, SO_SNDBUF, &kSocketBuffer, sizeof kSocketBuffer);
      // The welcome goes out before the member is in the forwarding set, so it is always first.
      const WireMsg welcome = wire::welcome();
      if (::send(fd.get(), &welcome, sizeof welcome, MSG_DONTWAIT | MSG_NOSIGNAL) != kMsgSize) continue;
      if (!detail::epoll_add(epoll_.get(), fd.get())) continue;
      members_.push_back(Member{std::move(fd)});
    }
  }

  // Reads what a member sent in batches (one recvmmsg each) and forwards each batch to every other
  // member with one sendmmsg: at full load the hub otherwise makes two system calls per frame.
  void pump(int fd) {
    const auto it = std::find_if(members_.begin(), members_.end(), [fd](const Member& m) { return m.fd.get() == fd; });
    if (it == members_.end()) return;
    for (int read = 0; read < kPumpBatch && !it->gone;) {
      const int n = ::recvmmsg(fd, in_.hdr.data(), WireBatch::kSize, MSG_DONTWAIT, nullptr);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
      if (n <= 0) {
        it->gone = true;  // reset: the member left
        return;
      }
      read += n;
      unsigned frames = 0;
      for (int i = 0; i < n; ++i) {
        const auto len = in_.hdr[static_cast<std::size_t>(i)].msg_len;
        if (len == 0) {
          it->gone = true;  // EOF: the member left; what it sent before still goes out
          break;
        }
        // A message of the wrong size is not ours; skip it.
        if (len == kMsgSize && in_.msgs[static_cast<std::size_t>(i)].kind == Kind::frame) {
          out_.msgs[frames++] = in_.msgs[static_cast<std::size_t>(i)];
        }
      }
      forward(frames, fd);
    }
  }

  void forward(unsigned count, int from_fd) {
    if (count == 0) return;
    for (Member& m : members_) {
      if (m.gone || m.fd.get() == from_fd) continue;
      if (m.overflowed) {
        if (!deliver(m, overflow_notice())) continue;
        m.overflowed = false;
      }
      for (unsigned i = 0; i < count;) {
        const int sent = ::sendmmsg(m.fd.get(), out_.hdr.data() + i, count - i, MSG_DONTWAIT | MSG_NOSIGNAL);
        if (sent > 0) {
          i += static_cast<unsigned>(sent);
          continue;
        }
        if (sent < 0 && errno == EINTR) continue;
        // Never waits: a member whose queue is full loses these frames, so one slow member cannot
        // stall the bus for the others.
        if (sent < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) {
          m.overflowed = true;
        } else {
          m.gone = true;
        }
        break;
      }
    }
  }

  static bool deliver(Member& m, const WireMsg& msg) {
    const ssize_t n = ::send(m.fd.get(), &msg, sizeof msg, MSG_DONTWAIT | MSG_NOSIGNAL);
    if (n == kMsgSize) return true;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) {
      m.overflowed = true;
    } else {
      m.gone = true;
    }
    return false;
  }

  void sweep() {
    std::erase_if(members_, [this](const Member& m) {
      if (m.gone) ::epoll_ctl(epoll_.get(), EPOLL_CTL_DEL, m.fd.get(), nullptr);
      return m.gone;
    });
  }

  UniqueFd listener_;
  UniqueFd epoll_;
  UniqueFd wake_;
  std::vector<Member> members_;  // touched by the hub thread only
  WireBatch in_;                 // hub thread only
  WireBatch out_;                // hub thread only
  std::atomic<bool> running_{true};
  std::thread thread_;  // last: starts once everything above exists
};

// -------------------------------------------------------------------------------------------------

Result<void> VirtualBus::check_name(std::string_view name) {
  if (valid_name(name)) return {};
  return make_error("virtual:" + std::string(name.substr(0, 100)) + (name.size() > 100 ? "..." : "") +
                    ": the bus name must be 1 to " + std::to_string(kMaxNameLen) + " characters of A-Z a-z 0-9 . _ -");
}

Result<std::unique_ptr<VirtualBus>> VirtualBus::open(std::string_view name) {
  std::string uri = "virtual:" + std::string(name);
  if (auto ok = check_name(name); !ok) return ok.error();
  UniqueFd epoll{::epoll_create1(EPOLL_CLOEXEC)};
  UniqueFd timer{::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC)};
  if (!epoll || !timer || !detail::epoll_add(epoll.get(), timer.get())) {
    return make_error(uri + ": cannot create descriptors: " + errno_text(errno));
  }
  std::string address(1, '\0');
  address.append(kAddressPrefix).append(name);
  auto bus = std::make_unique<VirtualBus>(PrivateTag{}, std::move(uri), std::move(address), std::move(epoll),
                                          std::move(timer));

  // Only races with another member's election or a hub going away end up here more than once.
  const auto deadline = std::chrono::steady_clock::now() + kOpenTimeout;
  for (;;) {
    auto joined = bus->join();
    if (!joined) return joined.error();
    if (*joined) {
      auto welcomed = bus->await_welcome(deadline);
      if (!welcomed) return welcomed.error();
      if (*welcomed) return bus;
      bus->leave();
    }
    if (std::chrono::steady_clock::now() >= deadline) {
      return make_error(bus->uri_ + ": no hub could be joined within 2 s");
    }
    std::this_thread::sleep_for(kJoinRetryPause);
  }
}

// What one recvmmsg fetched, handed out one frame per receive().
struct VirtualBus::RxBatch {
  WireBatch batch;
  unsigned count = 0;  // messages in batch
  unsigned next = 0;   // the next one to hand out
};

VirtualBus::VirtualBus(PrivateTag, std::string uri, std::string address, UniqueFd epoll, UniqueFd retry_timer)
    : uri_(std::move(uri)),
      address_(std::move(address)),
      epoll_(std::move(epoll)),
      retry_timer_(std::move(retry_timer)),
      rx_(std::make_unique<RxBatch>()) {}

VirtualBus::~VirtualBus() {
  leave();
  hub_.reset();  // stops and joins the hub thread; the other members re-elect
}

bool VirtualBus::owns_hub() const { return hub_ && hub_->running(); }

// Becomes the hub if nobody is, then connects to the hub. True when connected; false when the hub
// is changing hands right now (address taken but refusing), so the caller retries a bit later.
Result<bool> VirtualBus::join() {
  const UnixAddress addr = unix_address(address_);

  UniqueFd listener = seqpacket_socket();
  if (!listener) return make_error(uri_ + ": cannot create a socket: " + errno_text(errno));
  if (::bind(listener.get(), addr.get(), addr.len) == 0) {
    if (::listen(listener.get(), SOMAXCONN) != 0) return make_error(uri_ + ": listen failed: " + errno_text(errno));
    auto hub = Hub::start(std::move(listener), uri_);
    if (!hub) return hub.error();
    hub_ = std::move(*hub);  // replaces a hub of ours that stopped on its own, if any
  } else if (errno != EADDRINUSE) {
    return make_error(uri_ + ": cannot bind the hub address: " + errno_text(errno));
  }

  UniqueFd sock = seqpacket_socket();
  if (!sock) return make_error(uri_ + ": cannot create a socket: " + errno_text(errno));
  if (::connect(sock.get(), addr.get(), addr.len) != 0) {
    const int err = errno;
    // Refused: bound but not (or no longer) listening. EAGAIN: backlog full. Both pass quickly.
    if (err == ECONNREFUSED || err == EAGAIN || err == ENOENT) return false;
    return make_error(uri_ + ": cannot connect to the hub: " + errno_text(err));
  }
  if (!detail::epoll_add(epoll_.get(), sock.get()))
    return make_error(uri_ + ": epoll_ctl failed: " + errno_text(errno));
  sock_ = std::move(sock);
  set_retry_timer(false);
  return true;
}

Result<bool> VirtualBus::await_welcome(std::chrono::steady_clock::time_point deadline) {
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline -
                                                                            std::chrono::steady_clock::now());
    if (left.count() <= 0) {
      return make_error(uri_ + ": the hub does not answer (is the process that hosts it stopped?)");
    }
    pollfd p{sock_.get(), POLLIN, 0};
    const int r = ::poll(&p, 1, static_cast<int>(left.count()));
    if (r < 0 && errno != EINTR) return make_error(uri_ + ": poll failed: " + errno_text(errno));
    if (r <= 0) continue;
    WireMsg msg;
    const ssize_t n = ::recv(sock_.get(), &msg, sizeof msg, MSG_DONTWAIT);
    if (n == kMsgSize && msg.kind == Kind::welcome) {
      if (msg.id != wire::kMagic) return make_error(uri_ + ": the hub speaks another wire format version");
      return true;
    }
    if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) return false;
  }
}

void VirtualBus::leave() {
  if (!sock_) return;
  ::epoll_ctl(epoll_.get(), EPOLL_CTL_DEL, sock_.get(), nullptr);
  sock_.reset();
}

Result<void> VirtualBus::rejoin() {
  leave();
  auto joined = join();
  if (joined && *joined) return {};
  // The timer makes fd() readable again later, so a caller that only waits on fd() still retries.
  set_retry_timer(true);
  if (!joined) return joined.error();
  return {};
}

void VirtualBus::set_retry_timer(bool armed) {
  itimerspec spec{};
  spec.it_value.tv_nsec = armed ? kHubRetryIntervalNs : 0;
  ::timerfd_settime(retry_timer_.get(), 0, &spec, nullptr);  // also clears a pending expiry
}

Result<std::optional<CanFrame>> VirtualBus::receive() {
  for (;;) {
    while (rx_->next < rx_->count) {
      const WireMsg& msg = rx_->batch.msgs[rx_->next];
      const auto len = rx_->batch.hdr[rx_->next].msg_len;
      ++rx_->next;
      if (len == 0) {  // EOF: the hub went away. Elect or join the next one; no frame this time.
        rx_->next = rx_->count = 0;
        if (auto r = rejoin(); !r) return r.error();
        return std::optional<CanFrame>{};
      }
      // Welcomes after a re-join and anything malformed are not frames.
      const auto decoded = wire::decode({reinterpret_cast<const std::uint8_t*>(&msg), len});
      if (!decoded) continue;
      CanFrame frame = *decoded;
      // Stamped with the moment it went on the bus (its sender's send, same machine and clock), as
      // SocketCAN stamps a frame when the controller took it off the wire: not with when this
      // member got around to reading it. A stamp from the future or over 10 s old is not taken.
      const auto now = detail::realtime_ns();
      frame.timestamp_ns = msg.timestamp_ns <= now && now - msg.timestamp_ns < 10'000'000'000 ? msg.timestamp_ns : now;
      ++(frame.error ? stats_.error_frames : stats_.frames_in);
      return std::optional<CanFrame>{frame};
    }
    rx_->next = rx_->count = 0;
    if (!sock_) {
      if (auto r = rejoin(); !r) return r.error();
      if (!sock_) return std::optional<CanFrame>{};
    }
    const int n = ::recvmmsg(sock_.get(), rx_->batch.hdr.data(), WireBatch::kSize, MSG_DONTWAIT, nullptr);
    if (n > 0) {
      rx_->count = static_cast<unsigned>(n);
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return std::optional<CanFrame>{};
    // EOF or reset: the hub went away. Elect or join the next one; no frame this time.
    if (auto r = rejoin(); !r) return r.error();
    return std::optional<CanFrame>{};
  }
}

Result<void> VirtualBus::send(const CanFrame& frame) {
  if (auto ok = detail::check_sendable(frame, uri_); !ok) return ok;
  const WireMsg msg = wire::encode(frame, detail::realtime_ns());
  // Second attempt only after the hub connection was found dead and replaced.
  for (int attempt = 0; attempt < 2; ++attempt) {
    if (!sock_) {
      if (auto r = rejoin(); !r) {
        ++stats_.tx_dropped;
        return r;
      }
      if (!sock_) break;
    }
    const ssize_t n = ::send(sock_.get(), &msg, sizeof msg, MSG_DONTWAIT | MSG_NOSIGNAL);
    if (n == kMsgSize) {
      ++stats_.frames_out;
      return {};
    }
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) {
      ++stats_.tx_dropped;
      return make_error(uri_ + ": transmit queue full, frame dropped");
    }
    leave();  // EPIPE, ECONNRESET, ...: the hub is gone
  }
  ++stats_.tx_dropped;
  return make_error(uri_ + ": no hub reachable (the bus is changing hands), frame dropped");
}

}  // namespace lb::can
