#pragma once
// HTTP over a plain socket, written by hand: a test sends exactly the bytes it means (a method the
// server must refuse, a head larger than its bound) and reads what comes back until the server
// closes, bounded in time. IPv4 only.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <string>

namespace lb::test {

struct HttpAnswer {
  int connect_errno = 0;  // connect() failed with it (ECONNREFUSED: nothing listens)
  int status = 0;         // 0: no status line (closed without an answer, or not HTTP)
  std::string head;       // status line and headers
  std::string body;

  // A header's value (name matched without case), or "".
  std::string header(const std::string& name) const {
    std::string lower_head = head;
    for (auto& c : lower_head) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    std::string key = "\r\n" + name + ":";
    for (auto& c : key) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    const auto at = lower_head.find(key);
    if (at == std::string::npos) return {};
    auto start = at + key.size();
    while (start < head.size() && head[start] == ' ') ++start;
    const auto end = head.find("\r\n", start);
    return head.substr(start, end == std::string::npos ? std::string::npos : end - start);
  }
};

// A connected socket, or -errno.
inline int connect_tcp(const std::string& address, std::uint16_t port, std::chrono::milliseconds timeout) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return -errno;
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
  tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(port);
  ::inet_pton(AF_INET, address.c_str(), &addr.sin_addr);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0) {
    const int e = errno;
    ::close(fd);
    return -e;
  }
  return fd;
}

// Sends `request` as it is and reads until the server closes (or `timeout` passes without a byte).
inline HttpAnswer http_exchange(const std::string& address, std::uint16_t port, const std::string& request,
                                std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  HttpAnswer answer;
  const int fd = connect_tcp(address, port, timeout);
  if (fd < 0) {
    answer.connect_errno = -fd;
    return answer;
  }
  for (std::size_t sent = 0; sent < request.size();) {
    const auto n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server may refuse before it read everything: read what it said
    sent += static_cast<std::size_t>(n);
  }
  std::string all;
  char buffer[4096];
  while (true) {
    const auto n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n <= 0) break;
    all.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
  const auto end_of_head = all.find("\r\n\r\n");
  answer.head = all.substr(0, end_of_head);
  if (end_of_head != std::string::npos) answer.body = all.substr(end_of_head + 4);
  if (all.rfind("HTTP/1.", 0) == 0 && all.size() > 12) answer.status = std::stoi(all.substr(9, 3));
  return answer;
}

inline HttpAnswer http_get(const std::string& address, std::uint16_t port, const std::string& path,
                           std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  return http_exchange(address, port, "GET " + path + " HTTP/1.1\r\nHost: " + address + "\r\nConnection: close\r\n\r\n",
                       timeout);
}

}  // namespace lb::test
