#include "link/dds_channel.hpp"

#include <poll.h>
#include <sys/socket.h>

#include <cerrno>
#include <cstring>
#include <string>

namespace lb::link {
namespace {
// More lane descriptors than this in a Hello are closed unused (a bus process has one per bus).
constexpr std::size_t kMaxLanes = 64;
constexpr int kHelloWaitMs = 10'000;
}  // namespace

Result<std::unique_ptr<DdsChannel>> DdsChannel::connect(const std::string& path, int send_timeout_ms) {
  auto fd = connect_channel(path, send_timeout_ms);
  if (!fd) return fd.error();
  auto channel = greet(*fd, send_timeout_ms, kHelloWaitMs);
  if (channel && !*channel) {
    return make_error("channel " + path + ": no Hello from the bus side within " + std::to_string(kHelloWaitMs) +
                      " ms");
  }
  return channel;
}

Result<std::unique_ptr<DdsChannel>> DdsChannel::greet(UniqueFd& fd, int send_timeout_ms, int wait_ms) {
  pollfd p{fd.get(), POLLIN, 0};
  const int ready = ::poll(&p, 1, wait_ms);
  if (ready < 0 && errno != EINTR) return make_error(std::string("channel poll: ") + std::strerror(errno));
  if (ready <= 0) return std::unique_ptr<DdsChannel>{};
  // The Hello comes first, at once on accept.
  DatagramBuffer buffer;
  auto got = receive_with_fds(fd.get(), buffer.room(), kMaxLanes);
  if (!got) return make_error("no Hello from the bus side: " + got.error().message);
  auto message = decode(buffer.first(got->size));
  if (!message) return message.error();
  auto* hello = std::get_if<Hello>(&*message);
  if (hello == nullptr) return make_error("the bus side's first message is not its Hello");
  // Lanes beyond the descriptors that came are served on the channel (send(lane, ...)).
  if (got->fds.size() > hello->lanes) got->fds.resize(hello->lanes);
  for (auto& lane : got->fds) {
    const timeval tv{send_timeout_ms / 1000, (send_timeout_ms % 1000) * 1000};
    ::setsockopt(lane.get(), SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof(tv));
  }
  return std::make_unique<DdsChannel>(std::move(fd), std::move(*hello), std::move(got->fds));
}

DdsChannel::DdsChannel(UniqueFd fd, Hello hello, std::vector<UniqueFd> lanes)
    : fd_(std::move(fd)), hello_(std::move(hello)), lanes_(std::move(lanes)) {}

Result<std::optional<Message>> DdsChannel::receive(int timeout_ms) {
  // What already waits is taken without a poll first: under load that is every message.
  const auto room = buffer_.room();
  auto n = ::recv(fd_.get(), room.data(), room.size(), MSG_DONTWAIT);
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
    pollfd p{fd_.get(), POLLIN, 0};
    const int ready = ::poll(&p, 1, timeout_ms);
    if (ready < 0) {
      if (errno == EINTR) return std::optional<Message>{};
      return make_error(std::string("channel poll: ") + std::strerror(errno));
    }
    if (ready == 0) return std::optional<Message>{};
    n = ::recv(fd_.get(), room.data(), room.size(), MSG_DONTWAIT);
  }
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR) return std::optional<Message>{};
    return make_error(std::string("channel: ") + std::strerror(errno));
  }
  if (n == 0) return make_error("the bus side closed the channel");
  auto message = decode(buffer_.first(static_cast<std::size_t>(n)));
  if (!message) return message.error();
  return std::optional<Message>(std::move(*message));
}

bool DdsChannel::send_on(int fd, const Message& message) const {
  const auto datagram = encode(message);
  return ::send(fd, datagram.data(), datagram.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(datagram.size());
}

bool DdsChannel::send(const Message& message) { return send_on(fd_.get(), message); }

bool DdsChannel::send(std::uint32_t lane, Sample sample) {
  sample.connection = hello_.connection;
  const int fd = lane == 0 || lane > lanes_.size() ? fd_.get() : lanes_[lane - 1].get();
  return send_on(fd, Message(std::move(sample)));
}

}  // namespace lb::link
