#include "link/dds_channel.hpp"

#include <poll.h>
#include <sys/socket.h>

#include <cerrno>
#include <cstring>

namespace lb::link {

Result<std::unique_ptr<DdsChannel>> DdsChannel::connect(const std::string& path, int send_timeout_ms) {
  auto fd = connect_channel(path, send_timeout_ms);
  if (!fd) return fd.error();
  return std::make_unique<DdsChannel>(std::move(*fd));
}

Result<std::optional<Message>> DdsChannel::receive(int timeout_ms) {
  pollfd p{fd_.get(), POLLIN, 0};
  const int ready = ::poll(&p, 1, timeout_ms);
  if (ready < 0) {
    if (errno == EINTR) return std::optional<Message>{};
    return make_error(std::string("channel poll: ") + std::strerror(errno));
  }
  if (ready == 0) return std::optional<Message>{};
  const auto n = ::recv(fd_.get(), buffer_.data(), buffer_.size(), MSG_DONTWAIT);
  if (n < 0) {
    if (errno == EAGAIN || errno == EINTR) return std::optional<Message>{};
    return make_error(std::string("channel: ") + std::strerror(errno));
  }
  if (n == 0) return make_error("the bus side closed the channel");
  auto message = decode(std::span(buffer_.data(), static_cast<std::size_t>(n)));
  if (!message) return message.error();
  return std::optional<Message>(std::move(*message));
}

bool DdsChannel::send(const Message& message) {
  const auto datagram = encode(message);
  return ::send(fd_.get(), datagram.data(), datagram.size(), MSG_NOSIGNAL) == static_cast<ssize_t>(datagram.size());
}

}  // namespace lb::link
