#include "app/observability/http_server.hpp"

#include <civetweb.h>
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <array>
#include <string_view>

#include "app/observability/metrics_text.hpp"
#include "app/observability/status_page.hpp"
#include "base/shared_log_rate.hpp"

namespace lb::app::obs {
namespace {

// Headers of every answer: nothing is cached or framed, no type sniffed, nothing loaded from
// elsewhere (the page carries its own style; no script), and every connection ends with its answer.
constexpr std::string_view kCommonHeaders =
    "Cache-Control: no-store\r\n"
    "X-Content-Type-Options: nosniff\r\n"
    "Content-Security-Policy: default-src 'none'; style-src 'unsafe-inline'; base-uri 'none'; form-action 'none'; "
    "frame-ancestors 'none'\r\n"
    "Referrer-Policy: no-referrer\r\n"
    "X-Frame-Options: DENY\r\n"
    "Connection: close\r\n";

int answer(mg_connection* conn, bool head, int status, std::string_view reason, std::string_view content_type,
           std::string_view body, std::string_view extra_headers = {}) {
  const auto header = fmt::format("HTTP/1.1 {} {}\r\nContent-Type: {}\r\nContent-Length: {}\r\n{}{}\r\n", status,
                                  reason, content_type, body.size(), kCommonHeaders, extra_headers);
  mg_write(conn, header.data(), header.size());
  if (!head && !body.empty()) mg_write(conn, body.data(), body.size());
  return status;
}

}  // namespace

Result<std::unique_ptr<ObservabilityServer>> ObservabilityServer::start(const Options& options,
                                                                        const LineViewKeeper& keeper) {
  std::unique_ptr<ObservabilityServer> server(new ObservabilityServer(keeper));  // private constructor
  const auto threads = std::to_string(options.threads);
  const auto queue = std::to_string(options.queue);
  const auto backlog = std::to_string(options.backlog);
  const auto max_request = std::to_string(options.max_request_bytes);
  const auto timeout = std::to_string(options.request_timeout.count());
  // No document_root: civetweb serves no file, and every request goes to on_request first.
  const std::array<const char*, 19> config{"listening_ports",
                                           options.listen.c_str(),
                                           "num_threads",
                                           threads.c_str(),
                                           "connection_queue",
                                           queue.c_str(),
                                           "listen_backlog",
                                           backlog.c_str(),
                                           "max_request_size",
                                           max_request.c_str(),
                                           "request_timeout_ms",
                                           timeout.c_str(),
                                           "enable_keep_alive",
                                           "no",
                                           "enable_directory_listing",
                                           "no",
                                           "decode_url",
                                           "yes",
                                           nullptr};
  mg_callbacks callbacks{};
  callbacks.begin_request = &ObservabilityServer::on_request;
  callbacks.log_message = &ObservabilityServer::on_log;
  std::array<char, 256> error_text{};
  unsigned error_code = 0;
  mg_error_data error{&error_code, error_text.data(), error_text.size()};
  mg_init_data init{&callbacks, server.get(), const_cast<const char**>(config.data())};
  mg_init_library(0);
  server->context_ = mg_start2(&init, &error);
  if (server->context_ == nullptr) {
    mg_exit_library();
    const std::string why = error_text[0] != '\0' ? std::string(error_text.data()) : "civetweb did not start";
    return make_error("cannot listen on " + options.listen + ": " + why);
  }
  std::array<mg_server_port, 4> ports{};
  if (mg_get_server_ports(server->context_, static_cast<int>(ports.size()), ports.data()) > 0)
    server->port_ = static_cast<std::uint16_t>(ports[0].port);
  return server;
}

ObservabilityServer::~ObservabilityServer() {
  if (context_ != nullptr) {
    mg_stop(context_);  // waits for the requests being served (bounded by request_timeout)
    mg_exit_library();
  }
}

int ObservabilityServer::on_request(mg_connection* conn) {
  const auto* self = static_cast<const ObservabilityServer*>(mg_get_user_data(mg_get_context(conn)));
  const mg_request_info* request = mg_get_request_info(conn);
  const std::string_view method = request->request_method != nullptr ? request->request_method : "";
  const std::string_view path = request->local_uri != nullptr ? request->local_uri : "";
  const bool head = method == "HEAD";
  if (method != "GET" && !head) {
    return answer(conn, false, 405, "Method Not Allowed", "text/plain; charset=utf-8",
                  "405 method not allowed: this server only shows the line (GET)\n", "Allow: GET, HEAD\r\n");
  }
  if (path == "/") {
    return answer(conn, head, 200, "OK", "text/html; charset=utf-8", render_status_page(self->keeper_.get()));
  }
  if (path == "/metrics") {
    return answer(conn, head, 200, "OK", "text/plain; version=0.0.4; charset=utf-8",
                  render_metrics(self->keeper_.get()));
  }
  return answer(conn, head, 404, "Not Found", "text/plain; charset=utf-8",
                "404 not found: / (the status page) and /metrics are served here\n");
}

int ObservabilityServer::on_log(const mg_connection* conn, const char* message) {
  const auto* context = conn != nullptr ? mg_get_context(conn) : nullptr;
  auto* self = context != nullptr ? static_cast<ObservabilityServer*>(mg_get_user_data(context)) : nullptr;
  if (self == nullptr) {
    spdlog::warn("observability: {}", message);
  } else if (const auto note = self->log_rate_.allow()) {
    spdlog::warn("observability: {}{}", message, *note);
  }
  return 1;  // logged here, not by civetweb
}

}  // namespace lb::app::obs
