#pragma once
// The DDS process's end of the channel: it connects to the bus process's socket, takes its Hello
// (with the lanes' descriptors), reads the declarations, snapshot and samples the bus side sends,
// and sends it the samples DDS delivers: a lane reader's on its lane, straight to its bus loop.
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
  // Waits up to 10 s for the bus side's Hello (it is sent once the bus side accepts).
  static Result<std::unique_ptr<DdsChannel>> connect(const std::string& path, int send_timeout_ms);
  // On a socket already connected (connect_channel): the channel once the Hello came, nullptr when
  // it did not within wait_ms (`fd` is then kept for another try: a bus process accepts only once
  // its line is set up). An error is the bus side's answer (closed, another version, not a Hello).
  static Result<std::unique_ptr<DdsChannel>> greet(UniqueFd& fd, int send_timeout_ms, int wait_ms);
  DdsChannel(UniqueFd fd, Hello hello, std::vector<UniqueFd> lanes);

  // The bus side's Hello of this connection.
  const Hello& hello() const { return hello_; }

  // The next message; nullopt when none came within timeout_ms; an error when the bus side closed
  // the channel or sent something that is not a message of this version (the connection is then
  // of no use: the caller ends).
  Result<std::optional<Message>> receive(int timeout_ms);
  // Any thread (a datagram is sent whole or not at all). False when the bus side did not take it in
  // time or is gone.
  bool send(const Message& message);
  // A sample of a reader declared on `lane`: on that lane, stamped with this connection; on the
  // channel when this side has no such lane.
  bool send(std::uint32_t lane, Sample sample);

 private:
  bool send_on(int fd, const Message& message) const;

  UniqueFd fd_;
  Hello hello_;
  std::vector<UniqueFd> lanes_;
  DatagramBuffer buffer_;
};

}  // namespace lb::link
