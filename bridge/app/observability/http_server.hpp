#pragma once
// ObservabilityServer: the DDS process's read-only HTTP server (civetweb, Debian's libcivetweb 1.15):
//   /         the status page (status_page.hpp), refreshing itself
//   /metrics  the Prometheus text format (metrics_text.hpp)
// and nothing else (404). It never takes a command: GET and HEAD only (any other method: 405 with
// Allow), no file is served, no request body is read, a request's head is bounded (413 beyond it),
// and so are the connections it serves at once (worker threads, a queue and the listen backlog).
// It shows what the line's diagnostics show, nothing secret (no key, no grant, no file path of the
// security files). Only the DDS process runs one: the bus process never opens a listening socket.
// civetweb is used directly: prometheus-cpp's exposer can neither refuse a method nor serve a page.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "app/observability/line_view.hpp"
#include "base/result.hpp"
#include "base/shared_log_rate.hpp"

struct mg_context;
struct mg_connection;

namespace lb::app::obs {

class ObservabilityServer {
 public:
  struct Options {
    std::string listen = "127.0.0.1:9420";            // civetweb's spelling: 127.0.0.1:9420, [::1]:9420
    int threads = 4;                                  // requests served at once
    int queue = 16;                                   // accepted connections waiting for a thread
    int backlog = 16;                                 // connections the kernel holds before accepting
    std::size_t max_request_bytes = 8192;             // a request's head (line and headers)
    std::chrono::milliseconds request_timeout{5000};  // a slow client holds a thread no longer
  };

  // Listens at once; an error says why not (the address taken, not on this machine).
  static Result<std::unique_ptr<ObservabilityServer>> start(const Options& options, const LineViewKeeper& keeper);
  ~ObservabilityServer();
  ObservabilityServer(const ObservabilityServer&) = delete;
  ObservabilityServer& operator=(const ObservabilityServer&) = delete;

  std::uint16_t port() const { return port_; }  // as bound

 private:
  explicit ObservabilityServer(const LineViewKeeper& keeper) : keeper_(keeper) {}
  static int on_request(mg_connection* conn);
  static int on_log(const mg_connection* conn, const char* message);

  const LineViewKeeper& keeper_;
  // civetweb's complaints (a request too large, a client gone mid-answer) come from any client:
  // they must not flood the log.
  SharedLogRate log_rate_{2};
  mg_context* context_ = nullptr;
  std::uint16_t port_ = 0;
};

}  // namespace lb::app::obs
