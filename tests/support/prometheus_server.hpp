#pragma once
// A real Prometheus server (Debian package prometheus) started by a test: it scrapes the given
// targets every second, keeps its data in a directory of the test's own, listens on a free
// loopback port, and answers PromQL over its HTTP API (/api/v1/query). Run inside the test's
// network namespace like every other process of an integration test.

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "support/child_process.hpp"
#include "support/eventually.hpp"
#include "support/scratch_files.hpp"

namespace lb::test {

inline constexpr const char* kPrometheus = "/usr/bin/prometheus";

// A loopback port nobody listens on now (the kernel's choice; free until someone binds it).
inline std::uint16_t free_loopback_port() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) throw std::runtime_error("socket failed");
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof a;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    ::close(fd);
    throw std::runtime_error("no free loopback port");
  }
  ::close(fd);
  return ntohs(a.sin_port);
}

struct HttpAnswer {
  int status = 0;  // 0: no answer (refused, timed out, cut)
  std::string body;
};

// GET http://127.0.0.1:port<target> (HTTP/1.0, the connection closed by the server), bounded.
inline HttpAnswer http_get(std::uint16_t port, const std::string& target,
                           std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
  HttpAnswer answer;
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return answer;
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = htons(port);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) return answer;
  const std::string request = "GET " + target + " HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n";
  if (::send(fd, request.data(), request.size(), MSG_NOSIGNAL) != static_cast<ssize_t>(request.size())) return answer;
  std::string raw;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  char buffer[8192];
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline -
                                                                            std::chrono::steady_clock::now());
    if (left.count() <= 0) return answer;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, static_cast<int>(left.count())) <= 0) return answer;
    const auto n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n < 0) return answer;
    if (n == 0) break;
    raw.append(buffer, static_cast<std::size_t>(n));
  }
  const auto head_end = raw.find("\r\n\r\n");
  if (raw.rfind("HTTP/1.", 0) != 0 || head_end == std::string::npos || raw.size() < 12) return answer;
  answer.status = std::stoi(raw.substr(9, 3));
  answer.body = raw.substr(head_end + 4);
  return answer;
}

inline std::string url_encode(const std::string& s) {
  static const char* const kHex = "0123456789ABCDEF";
  std::string out;
  for (const unsigned char c : s) {
    if ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_' ||
        c == '.' || c == '~') {
      out.push_back(static_cast<char>(c));
    } else {
      out += {'%', kHex[c >> 4], kHex[c & 0xF]};
    }
  }
  return out;
}

// An answer of /api/v1/query, as much of it as the tests read: whether it succeeded (else the
// error Prometheus gave), and the sample values of an instant vector, in order.
struct PromAnswer {
  bool success = false;
  std::string error;
  std::vector<std::string> values;  // each result's value as Prometheus writes it ("1", "0.5", "NaN")
  std::string json;                 // the whole answer
};

inline PromAnswer parse_prom_answer(const HttpAnswer& http) {
  PromAnswer a;
  a.json = http.body;
  a.success = http.body.find("\"status\":\"success\"") != std::string::npos;
  if (const auto at = http.body.find("\"error\":\""); at != std::string::npos) {
    for (auto i = at + 9; i < http.body.size() && http.body[i] != '"'; ++i) {
      if (http.body[i] == '\\' && i + 1 < http.body.size()) ++i;  // an escaped character: taken as it is
      a.error.push_back(http.body[i]);
    }
  }
  if (!a.success && a.error.empty()) a.error = "HTTP " + std::to_string(http.status) + ": " + http.body;
  // "value":[<time>,"<value>"] per result of a vector; a scalar's "result":[<time>,"<value>"].
  for (std::size_t at = http.body.find("\"value\":["); at != std::string::npos;
       at = http.body.find("\"value\":[", at + 1)) {
    const auto open = http.body.find(",\"", at);
    if (open == std::string::npos) break;
    a.values.push_back(http.body.substr(open + 2, http.body.find('"', open + 2) - open - 2));
  }
  return a;
}

class PrometheusServer {
 public:
  // Scrapes each target (host:port, path /metrics) every second as job "linebridge".
  explicit PrometheusServer(const std::vector<std::string>& targets) : port_(free_loopback_port()) {
    dir_ = fresh_dir("prometheus");
    std::string list;
    for (const auto& t : targets) list += (list.empty() ? "'" : ", '") + t + "'";
    std::ofstream(dir_ + "/prometheus.yml")
        << "global:\n  scrape_interval: 1s\n  evaluation_interval: 1s\n"
        << "scrape_configs:\n  - job_name: linebridge\n"
        << "    scrape_timeout: 1s\n    static_configs:\n      - targets: [" << list << "]\n";
    process_ = std::make_unique<ChildProcess>(
        std::vector<std::string>{kPrometheus, "--config.file=" + dir_ + "/prometheus.yml",
                                 "--storage.tsdb.path=" + dir_ + "/data",
                                 "--web.listen-address=127.0.0.1:" + std::to_string(port_), "--log.level=warn"},
        dir_ + "/prometheus.log");
  }

  // Ready to answer queries (/-/ready), within timeout.
  bool wait_ready(std::chrono::seconds timeout = std::chrono::seconds(60)) {
    return eventually(timeout, [&] { return http_get(port_, "/-/ready", std::chrono::seconds(2)).status == 200; });
  }

  PromAnswer query(const std::string& promql) {
    return parse_prom_answer(http_get(port_, "/api/v1/query?query=" + url_encode(promql)));
  }

  std::uint16_t port() const { return port_; }
  std::string log() const { return process_->log(); }
  ChildProcess& process() { return *process_; }

 private:
  std::uint16_t port_;
  std::string dir_;
  std::unique_ptr<ChildProcess> process_;
};

}  // namespace lb::test
