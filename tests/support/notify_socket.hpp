#pragma once
// A systemd notification socket of the test's own (NOTIFY_SOCKET), to read what a service sends
// with sd_notify: READY=1, WATCHDOG=1, STOPPING=1.

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <string>

#include "can/unique_fd.hpp"

namespace lb::test {

using Clock = std::chrono::steady_clock;

class NotifySocket {
 public:
  NotifySocket() : path_(::testing::TempDir() + "/notify_" + std::to_string(::getpid())) {
    ::unlink(path_.c_str());
    fd_.reset(::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0));
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    path_.copy(a.sun_path, sizeof a.sun_path - 1);
    EXPECT_EQ(::bind(fd_.get(), reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    timeval tv{0, 100'000};
    ::setsockopt(fd_.get(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    ::setenv("NOTIFY_SOCKET", path_.c_str(), 1);
  }
  ~NotifySocket() {
    ::unsetenv("NOTIFY_SOCKET");
    ::unlink(path_.c_str());
  }
  // The next message within `timeout`, "" if none.
  std::string next(Clock::duration timeout) {
    const auto end = Clock::now() + timeout;
    while (Clock::now() < end) {
      char buf[512];
      const auto n = ::recv(fd_.get(), buf, sizeof buf, 0);
      if (n > 0) return std::string(buf, static_cast<std::size_t>(n));
    }
    return "";
  }
  // Every message received during `d`.
  std::string during(Clock::duration d) {
    std::string all;
    const auto end = Clock::now() + d;
    while (Clock::now() < end) all += next(end - Clock::now()) + "|";
    return all;
  }

 private:
  std::string path_;
  lb::can::UniqueFd fd_;
};

}  // namespace lb::test
