#include "app/observability/status_page.hpp"

#include <fmt/format.h>

namespace lb::app::obs {

std::string html_escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      case '\'': out += "&#39;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string render_status_page(const LineView& view) {
  std::string page =
      fmt::format("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
                  "<meta http-equiv=\"refresh\" content=\"{}\"><title>linebridge: line {}</title></head><body>"
                  "<h1>Line {}</h1>",
                  kStatusPageRefreshSeconds, html_escape(view.line), html_escape(view.line));
  if (!view.diagnostics) {
    page += "<p id=\"waiting\">Waiting for the bus process: no diagnostics yet.</p>";
  } else {
    page += "<table><tr><th>Device</th><th>Node</th><th>State</th></tr>";
    for (const auto& n : view.diagnostics->nodes()) {
      page += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td></tr>", html_escape(n.device()), n.node_id(),
                          n.online() ? "ONLINE" : "LOST");
    }
    page += "</table>";
  }
  page += "</body></html>\n";
  return page;
}

}  // namespace lb::app::obs
