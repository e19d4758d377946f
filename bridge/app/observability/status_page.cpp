#include "app/observability/status_page.hpp"

#include <fmt/chrono.h>
#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <ctime>
#include <iterator>
#include <vector>

#include "app/nmt_text.hpp"
#include "canopen/emcy.hpp"

namespace lb::app::obs {
namespace {

namespace msg = linebridge_msgs::msg;

// A state as the page shows it: its words (what a reader goes by), and a class that colours it as
// a second cue only (ok, warn, bad, idle). The palette is Okabe and Ito's, which readers with any
// common colour-vision deficiency still tell apart; bad states are also bold and framed.
struct Shown {
  std::string words;
  std::string_view cls;
};

// After this long without a diagnostics sample the page says it is stale (the bus process sends
// one a second; a DDS side cut off from it ends itself within seconds).
constexpr double kStaleAfterS = 5.0;

constexpr std::string_view kStyle = R"(
body{font-family:sans-serif;margin:1em 2em;color:#111;background:#fff}
h1{margin:0 0 .2em 0;font-size:1.6em}
h2{margin:1.2em 0 .3em 0;font-size:1.25em}
.meta{color:#444;margin:.2em 0 1em 0}
table{border-collapse:collapse;margin:.4em 0 1em 0}
th,td{border:1px solid #bbb;padding:.25em .5em;text-align:left;vertical-align:top}
th{background:#eee}
dl.facts{display:grid;grid-template-columns:max-content auto;gap:.15em 1em;margin:.3em 0}
dl.facts dt{font-weight:bold}
dl.facts dd{margin:0}
.state{display:inline-block;padding:0 .35em;border-radius:.2em;font-weight:bold;letter-spacing:.03em}
.ok{background:#d9f2ea;color:#00543f}
.warn{background:#fbecc6;color:#6b4a00}
.bad{background:#f9dccb;color:#7a2f00;outline:2px solid #D55E00}
.idle{background:#e6eef6;color:#123e61}
tr.bad td:first-child{border-left:6px solid #D55E00}
tr.warn td:first-child{border-left:6px dashed #E69F00}
.why{color:#333;font-size:.92em}
code{font-size:.95em}
footer{margin-top:2em;color:#444;font-size:.9em;max-width:60em}
)";

template <class... Args>
void add(std::string& out, fmt::format_string<Args...> format, Args&&... args) {
  fmt::format_to(std::back_inserter(out), format, std::forward<Args>(args)...);
}

std::string badge(const Shown& s) {
  return fmt::format("<span class=\"state {}\">{}</span>", s.cls, html_escape(s.words));
}

std::string seconds(double s) {
  if (s < 0) return "-";
  if (s < 10) return fmt::format("{:.1f} s", s);
  if (s < 120) return fmt::format("{:.0f} s", s);
  if (s < 7200) return fmt::format("{:.0f} min", s / 60);
  return fmt::format("{:.1f} h", s / 3600);
}

}  // namespace

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

// CiA 302-2's boot error letters (the boot's step that failed), in words.
std::string_view boot_error_meaning(char letter) {
  switch (letter) {
    case 'A': return "the device is not in the network list";
    case 'B': return "no answer to the device type read (1000h)";
    case 'C': return "the device type (1000h) differs from the configured one";
    case 'D': return "the vendor-ID (1018h sub 1) differs";
    case 'E': return "no heartbeat from the device";
    case 'F': return "node guarding event";
    case 'G': return "application software version differs (program download)";
    case 'H': return "automatic software update not allowed (program download)";
    case 'I': return "automatic software update failed (program download)";
    case 'J': return "the configuration download failed";
    case 'K': return "heartbeat event during start of error control (no heartbeat after the boot)";
    case 'L': return "the device was already operational";
    case 'M': return "the product code (1018h sub 2) differs";
    case 'N': return "the revision number (1018h sub 3) differs";
    case 'O': return "the serial number (1018h sub 4) differs";
    default: return "not a CiA 302-2 boot error letter";
  }
}

namespace {

// Whether the device is heard, first: what a maintenance electrician looks for.
Shown health(const msg::NodeDiagnostics& n) {
  if (n.online()) return {"ONLINE", "ok"};
  if (n.last_heartbeat_age_s() < 0) return {"NOT HEARD", "warn"};
  return {"LOST", "bad"};
}

Shown node_state(const msg::NodeDiagnostics& n) {
  const std::string& s = n.node_state();
  std::string words = s.empty() ? "unknown" : s;
  std::transform(words.begin(), words.end(), words.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  if (s == "operational" || s == "monitored") return {words, "ok"};
  if (s == "lost" || s == "boot failed") return {words, "bad"};
  if (s == "booting" || s == "resetting" || s == "unknown" || s.empty()) return {words, "idle"};
  return {words, "warn"};  // stopped by operator or by the line, waiting, running unmanaged
}

// The node state's reason: why the line holds it, what its boot is doing, the boot error.
std::string state_reason(const msg::NodeDiagnostics& n) {
  std::string out;
  if (!n.line_hold().empty()) add(out, "<div class=\"why\">line hold: {}</div>", html_escape(n.line_hold()));
  if (!n.boot_state().empty() && n.boot_state() != n.node_state() && n.boot_state() != n.line_hold())
    add(out, "<div class=\"why\">{}</div>", html_escape(n.boot_state()));
  if (n.mandatory()) out += "<div class=\"why\">mandatory device</div>";
  return out;
}

std::string heartbeat(const msg::NodeDiagnostics& n) {
  if (n.last_heartbeat_age_s() < 0) return "none yet";
  return seconds(n.last_heartbeat_age_s()) + " ago";
}

std::string active_errors(const msg::NodeDiagnostics& n) {
  std::string out;
  if (n.active_errors().empty()) {
    out += n.active_errors_known() ? badge({"NONE", "ok"}) : badge({"NONE KNOWN", "idle"});
  } else {
    out += badge({fmt::format("{} ACTIVE", n.active_errors().size()), "bad"});
    out += "<ul class=\"errors\">";
    for (const auto code : n.active_errors())
      add(out, "<li><code>{:04X}h</code> {}</li>", code, html_escape(canopen::emcy_family(code)));
    out += "</ul>";
  }
  if (n.error_register() != 0) add(out, "<div class=\"why\">error register {:02X}h</div>", n.error_register());
  if (!n.active_errors_known()) {
    add(out, "<div class=\"why\">uncertain{}{}</div>", n.active_errors_note().empty() ? "" : ": ",
        html_escape(n.active_errors_note()));
  }
  return out;
}

std::string last_boot(const msg::NodeDiagnostics& n) {
  std::string out;
  const auto& e = n.boot_error();
  if (!e.code().empty()) {
    const char letter = e.code().front();
    out += badge({"FAILED (" + e.code() + ")", "bad"});
    add(out, "<div class=\"why\">{}: {}</div>", html_escape(e.code()), html_escape(boot_error_meaning(letter)));
    if (!e.message().empty()) add(out, "<div class=\"why\">{}</div>", html_escape(e.message()));
  } else if (n.last_boot_passed()) {
    out += n.adopted() ? badge({"ADOPTED RUNNING", "ok"}) : badge({"PASSED", "ok"});
  } else if (n.boots() == 0) {
    out += badge({n.node_state() == "monitored" ? "NOT BOOTED HERE" : "NONE YET", "idle"});
  } else {
    out += badge({"UNDER WAY", "idle"});
  }
  add(out, "<div class=\"why\">boots {}, failed {}, boot-ups {}</div>", n.boots(), n.boot_failures(), n.boot_ups());
  return out;
}

std::string device_cell(const msg::NodeDiagnostics& n) {
  std::string out = "<b>" + html_escape(n.device()) + "</b>";
  if (!n.product_name().empty()) add(out, "<div class=\"why\">{}</div>", html_escape(n.product_name()));
  return out;
}

std::string type_cell(const msg::NodeDiagnostics& n) {
  std::string out = html_escape(n.device_type().empty() ? "-" : n.device_type());
  if (!n.profile().empty()) add(out, "<div class=\"why\">{}</div>", html_escape(n.profile()));
  return out;
}

void node_row(std::string& out, const msg::NodeDiagnostics& n) {
  const Shown h = health(n);
  // The row's class follows the worse of health and boot: a lost or failed device stands out.
  std::string_view row = h.cls;
  if (row == "ok" && !n.boot_error().code().empty()) row = "bad";
  add(out,
      "<tr class=\"node {}\" id=\"node-{}\" data-device=\"{}\" data-health=\"{}\">"
      "<td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
      row, html_escape(n.device()), html_escape(n.device()), html_escape(h.words), n.node_id(), device_cell(n),
      type_cell(n), badge(h), html_escape(nmt_text(n.nmt_state())), badge(node_state(n)), state_reason(n), heartbeat(n),
      active_errors(n), last_boot(n));
}

Shown role(const msg::BusDiagnostics& b) {
  const std::string& r = b.role();
  if (r == "master") {
    if (b.yielding_to_other_master()) return {"MASTER, YIELDING (another master is heard)", "bad"};
    return {"MASTER", "ok"};
  }
  if (r == "monitor") return {"MONITOR (listen-only)", "idle"};
  if (r == "standby") return {"STANDBY (another bridge masters this bus)", "idle"};
  if (r.starts_with("standby, mastering")) return {"MASTERING (a standby that took over)", "ok"};
  return {r, "idle"};
}

Shown controller(const msg::BusDiagnostics& b) {
  std::string words = b.state();
  std::transform(words.begin(), words.end(), words.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  if (b.state() == "error-active") return {words, "ok"};
  if (b.state() == "bus-off" || b.state() == "down") return {words, "bad"};
  if (b.state() == "unknown") return {words, "idle"};
  return {words, "warn"};
}

// SYNC as this bridge produces it: the period, and how far its intervals strayed (the histogram's
// mean, and the smallest bound every interval stayed within).
std::string sync_text(const msg::BusDiagnostics& b) {
  if (b.sync_period_s() <= 0) {
    return b.role() == "monitor" ? "not produced here (listen-only)" : "not produced by this bridge";
  }
  std::string out = fmt::format("every {:.3g} ms, produced by this bridge", b.sync_period_s() * 1000);
  const auto& h = b.sync_period_deviation_s();
  if (h.count() == 0) return out + "; no interval measured yet";
  add(out, "; mean deviation {:.3f} ms over {} intervals", h.sum() / static_cast<double>(h.count()) * 1000, h.count());
  const auto n = std::min(h.upper_bounds().size(), h.cumulative_counts().size());
  for (std::size_t i = 0; i < n; ++i) {
    if (h.cumulative_counts()[i] == h.count()) {
      add(out, ", all within {:.3g} ms", h.upper_bounds()[i] * 1000);
      return out;
    }
  }
  if (n > 0)
    add(out, ", {} beyond {:.3g} ms", h.count() - h.cumulative_counts()[n - 1], h.upper_bounds()[n - 1] * 1000);
  return out;
}

void bus_section(std::string& out, const msg::BusDiagnostics& b, const msg::Diagnostics& d) {
  add(out, "<section class=\"bus\" id=\"bus-{}\"><h2>Bus {} <span class=\"why\">{}</span></h2>\n<dl class=\"facts\">",
      html_escape(b.name()), html_escape(b.name()), html_escape(b.interface_uri()));
  add(out, "<dt>Role</dt><dd>{}", badge(role(b)));
  if (!b.other_master_last().empty())
    add(out, " <span class=\"why\">last frame of another master: {}</span>", html_escape(b.other_master_last()));
  if (!b.takeover().empty()) add(out, " <span class=\"why\">{}</span>", html_escape(b.takeover()));
  out += "</dd>";
  if (!b.mandatory_state().empty()) add(out, "<dt>Mandatory devices</dt><dd>{}</dd>", html_escape(b.mandatory_state()));
  add(out, "<dt>SYNC</dt><dd>{}</dd>", html_escape(sync_text(b)));
  if (b.load_percent() < 0) {
    out += "<dt>Bus load</dt><dd>not measured (a replay at full speed)</dd>";
  } else {
    add(out, "<dt>Bus load</dt><dd>{:.1f} % <span class=\"why\">({:.0f} frames/s in, {:.0f} out)</span></dd>",
        b.load_percent(), b.frames_in_per_s(), b.frames_out_per_s());
  }
  add(out,
      "<dt>Controller</dt><dd>{} <span class=\"why\">TX errors {}, RX errors {}, bus-offs {}, error frames {}, "
      "overflows {}, frames dropped in {} / out {}{}</span></dd>",
      badge(controller(b)), b.tx_error_counter(), b.rx_error_counter(), b.bus_offs(), b.error_frames(),
      b.rx_overflows(), b.rx_dropped(), b.tx_dropped(), b.replay() ? "; a replayed recording (log:)" : "");
  out += "</dl>\n";
  std::vector<const msg::NodeDiagnostics*> nodes;
  for (const auto& n : d.nodes()) {
    if (n.bus() == b.name()) nodes.push_back(&n);
  }
  std::sort(nodes.begin(), nodes.end(), [](const auto* x, const auto* y) { return x->node_id() < y->node_id(); });
  if (nodes.empty()) {
    out += "<p>No device is configured on this bus.</p></section>\n";
    return;
  }
  out += "<table class=\"nodes\"><thead><tr><th>Node</th><th>Device</th><th>Type</th><th>Heard</th><th>NMT</th>"
         "<th>Node state</th><th>Last heartbeat</th><th>Active errors</th><th>Last boot</th></tr></thead><tbody>\n";
  for (const auto* n : nodes) node_row(out, *n);
  out += "</tbody></table></section>\n";
}

void dds_section(std::string& out, const LineView& view) {
  out += "<section id=\"dds\"><h2>DDS side</h2><dl class=\"facts\">";
  if (view.connected) {
    add(out, "<dt>Bus process</dt><dd>{} <span class=\"why\">for {}</span></dd>", badge({"CONNECTED", "ok"}),
        seconds(std::chrono::duration<double>(view.now - view.connected_since).count()));
  } else {
    add(out, "<dt>Bus process</dt><dd>{}</dd>", badge({"NOT CONNECTED", "warn"}));
  }
  add(out, "<dt>Clients</dt><dd>{} remote DDS participant(s){}</dd>", view.remote_participants,
      view.secured ? " (DDS Security in force: authenticated)" : "");
  add(out, "<dt>Samples</dt><dd>{} published to DDS; {} set values and requests not handed on in time",
      view.samples_published, view.samples_not_forwarded);
  if (view.diagnostics) {
    const auto& s = view.diagnostics->dds_side();
    add(out, "; {} dropped by the bus process (no DDS side, or its queue full); DDS sides connected: {}",
        s.samples_dropped(), s.connects());
    if (view.diagnostics->commands_lost() > 0)
      add(out, "; {} set values or requests lost on their way in", view.diagnostics->commands_lost());
  }
  out += "</dd>";
  if (view.remote_participants_refused > 0 || view.gate.evicted > 0) {
    add(out, "<dt>Refused</dt><dd>{} failed authentication, {} evicted unproven by the discovery gate</dd>",
        view.remote_participants_refused, view.gate.evicted);
  }
  out += "</dl></section>\n";
}

std::string utc(const msg::Time& t) {
  const std::time_t seconds_since_epoch = t.sec();
  return fmt::format("{:%Y-%m-%d %H:%M:%S} UTC", fmt::gmtime(seconds_since_epoch));
}

}  // namespace

std::string render_status_page(const LineView& view) {
  std::string out;
  out.reserve(16384);
  const auto line = html_escape(view.line);
  add(out,
      "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
      "<meta http-equiv=\"refresh\" content=\"{}\">"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
      "<title>linebridge: line {}</title><style>{}</style></head>\n<body>\n<header><h1>Line {}</h1>",
      kStatusPageRefreshSeconds, line, kStyle, line);
  if (!view.diagnostics) {
    add(out,
        "<p class=\"meta\">Read-only; this page refreshes itself every {} s.</p></header>\n"
        "<p id=\"waiting\">{} Waiting for the bus process: no diagnostics from it yet. {}</p>\n",
        kStatusPageRefreshSeconds, badge({"WAITING", "idle"}),
        view.connected ? "It let this DDS side in; its first diagnostics come within a second."
                       : "This DDS side is not connected to it yet (a standby's bus process lets it in once it "
                         "masters a bus).");
    dds_section(out, view);
  } else {
    const auto& d = *view.diagnostics;
    const double age = view.diagnostics_age_s();
    add(out, "<p class=\"meta\">Diagnostics of {} ({} ago){}; read-only, refreshes itself every {} s.</p></header>\n",
        utc(d.stamp()), seconds(age),
        age > kStaleAfterS ? " " + badge({"STALE: the bus process sends one a second", "bad"}) : std::string(),
        kStatusPageRefreshSeconds);
    for (const auto& b : d.buses()) bus_section(out, b, d);
    dds_section(out, view);
  }
  out += R"(<footer><p>What the bridge cannot tell: CAN is not authenticated. A device's state and errors are
what frames with its identifiers say: an EMCY that anything else on the bus sends with a device's
identifier shows here as that device's error, active until the device itself says otherwise (an
EMCY with error register 0, its boot-up, or its error register 1001h as the bridge reads it after a
boot). A heartbeat that stops means the device, its cable or the bus went silent: the page cannot
tell which.</p><p>linebridge status page: it shows, it never commands.</p></footer>
</body></html>
)";
  return out;
}

}  // namespace lb::app::obs
