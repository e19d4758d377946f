#pragma once
// The DDS process's end of the channel: it connects to the bus process's socket, reads the
// declarations, snapshot and samples the bus side sends, and sends it the samples DDS delivers.
// Blocking, with timeouts: this side may wait; the bus side never does.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "base/result.hpp"
#include "link/channel_message.hpp"
#include "link/channel_socket.hpp"

namespace lb::link {

class DdsChannel {
 public:
  // send_timeout_ms: how long a send may wait for the bus side to take it before it is dropped.
  static Result<std::unique_ptr<DdsChannel>> connect(const std::string& path, int send_timeout_ms);
  explicit DdsChannel(UniqueFd fd) : fd_(std::move(fd)) {}

  // The next message; nullopt when none came within timeout_ms; an error when the bus side closed
  // the channel or sent something that is not a message of this version (the connection is then
  // of no use: the caller ends).
  Result<std::optional<Message>> receive(int timeout_ms);
  // Any thread (a datagram is sent whole or not at all). False when the bus side did not take it in
  // time or is gone.
  bool send(const Message& message);

 private:
  UniqueFd fd_;
  std::vector<std::uint8_t> buffer_ = std::vector<std::uint8_t>(kMaxMessage);
};

}  // namespace lb::link
