// The status page's renderer on LineViews built by hand: every state in words, a lost device's row
// says lost, every string from the line file or the bus escaped, nothing loaded from elsewhere.
// Expected words come from the specifications (CiA 301 EMCY code families, CiA 302-2 boot error
// letters) and the page's own promise (words first), written out here.
#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "app/observability/status_page.hpp"

namespace msg = linebridge_msgs::msg;
using lb::app::obs::LineView;
using lb::app::obs::render_status_page;

namespace {

bool has(const std::string& text, const std::string& what) { return text.find(what) != std::string::npos; }

// The table row of one device (its <tr> up to </tr>); empty when the page has none.
std::string row_of(const std::string& page, const std::string& device) {
  const auto start = page.find("<tr class=\"node");
  for (auto at = start; at != std::string::npos; at = page.find("<tr class=\"node", at + 1)) {
    const auto end = page.find("</tr>", at);
    const auto row = page.substr(at, end - at);
    if (has(row, "id=\"node-" + device + "\"")) return row;
  }
  return {};
}

msg::BusDiagnostics bus(const std::string& name, const std::string& role) {
  msg::BusDiagnostics b;
  b.name(name);
  b.interface_uri("virtual:" + name);
  b.role(role);
  b.state("error-active");
  b.load_percent(12.5);
  return b;
}

msg::NodeDiagnostics node(const std::string& device, const std::string& bus_name, std::uint8_t id) {
  msg::NodeDiagnostics n;
  n.device(device);
  n.bus(bus_name);
  n.node_id(id);
  n.online(true);
  n.nmt_state(msg::NMT_OPERATIONAL);
  n.node_state("operational");
  n.boot_state("started");
  n.last_heartbeat_age_s(0.1);
  n.boots(1);
  n.last_boot_passed(true);
  n.active_errors_known(true);
  n.device_type("saw");
  n.profile("cia420-4 3.1");
  return n;
}

LineView view_with(msg::Diagnostics d) {
  LineView v;
  v.line = d.line();
  v.now = LineView::Clock::now();
  v.received = v.now - std::chrono::milliseconds(300);
  v.connected = true;
  v.connected_since = v.now - std::chrono::seconds(42);
  v.remote_participants = 3;
  v.diagnostics = std::make_shared<const msg::Diagnostics>(std::move(d));
  return v;
}

msg::Diagnostics line_of_two() {
  msg::Diagnostics d;
  d.line("demo");
  d.buses().push_back(bus("extrusion", "master"));
  d.nodes().push_back(node("saw1", "extrusion", 3));
  d.nodes().push_back(node("puller1", "extrusion", 2));
  return d;
}

}  // namespace

TEST(StatusPage, BeforeTheFirstDiagnosticsItSaysItWaitsForTheBusProcess) {
  LineView v;
  v.line = "demo";
  v.now = LineView::Clock::now();
  const auto page = render_status_page(v);
  EXPECT_TRUE(has(page, "<!DOCTYPE html>")) << page;
  EXPECT_TRUE(has(page, "Waiting for the bus process")) << page;
  EXPECT_TRUE(has(page, "NOT CONNECTED")) << page;
  EXPECT_TRUE(has(page, "<meta http-equiv=\"refresh\" content=\"2\">")) << page;
  EXPECT_FALSE(has(page, "<tr class=\"node")) << page;
}

TEST(StatusPage, AnOnlineAndALostDeviceInWords) {
  auto d = line_of_two();
  auto& saw = d.nodes()[0];
  saw.online(false);
  saw.nmt_state(msg::NMT_UNKNOWN);
  saw.node_state("lost");
  saw.boot_state("lost: no heartbeat for 500 ms");
  saw.last_heartbeat_age_s(3.2);
  const auto page = render_status_page(view_with(d));

  const auto lost = row_of(page, "saw1");
  ASSERT_FALSE(lost.empty()) << page;
  EXPECT_TRUE(has(lost, ">LOST<")) << lost;
  EXPECT_TRUE(has(lost, "data-health=\"LOST\"")) << lost;
  EXPECT_FALSE(has(lost, "ONLINE")) << lost;
  EXPECT_TRUE(has(lost, "3.2 s ago")) << lost;
  EXPECT_TRUE(has(lost, "no heartbeat for 500 ms")) << lost;  // the state's reason
  EXPECT_TRUE(has(lost, "class=\"node bad\"")) << lost;       // colour as a second cue

  const auto online = row_of(page, "puller1");
  ASSERT_FALSE(online.empty()) << page;
  EXPECT_TRUE(has(online, ">ONLINE<")) << online;
  EXPECT_TRUE(has(online, ">operational<")) << online;  // NMT state
  EXPECT_TRUE(has(online, ">OPERATIONAL<")) << online;  // node state
  EXPECT_TRUE(has(online, "PASSED")) << online;         // last boot
  EXPECT_FALSE(has(online, "LOST")) << online;
  // Rows by node-ID: puller1 (2) before saw1 (3), whatever order the sample has.
  EXPECT_LT(page.find("id=\"node-puller1\""), page.find("id=\"node-saw1\""));
}

TEST(StatusPage, StatesAndErrorsInWords) {
  auto d = line_of_two();
  auto& saw = d.nodes()[0];
  saw.nmt_state(msg::NMT_PRE_OPERATIONAL);
  saw.node_state("boot failed");
  saw.last_boot_passed(false);
  saw.boot_error().code("K");
  saw.boot_error().message("no heartbeat within 500 ms after the configuration");
  // CiA 301 EMCY codes: 4210h is a temperature error (4xxxh), 3120h a voltage error (3xxxh).
  saw.active_errors({0x4210, 0x3120});
  saw.error_register(0x0D);
  auto& puller = d.nodes()[1];
  puller.active_errors_known(false);
  puller.active_errors_note("an EMCY 0000h left errors the register still reports");
  puller.last_heartbeat_age_s(-1);
  puller.online(false);
  d.nodes().push_back(node("corrugator1", "extrusion", 4));
  d.nodes().back().line_hold("stopped: mandatory device saw1 lost");
  d.nodes().back().node_state("stopped by the line");
  d.nodes().back().nmt_state(msg::NMT_STOPPED);
  const auto page = render_status_page(view_with(d));

  const auto saw_row = row_of(page, "saw1");
  EXPECT_TRUE(has(saw_row, ">pre-operational<")) << saw_row;
  EXPECT_TRUE(has(saw_row, ">BOOT FAILED<")) << saw_row;
  EXPECT_TRUE(has(saw_row, "FAILED (K)")) << saw_row;
  // CiA 302-2: K is a heartbeat event during the start of error control.
  EXPECT_TRUE(has(saw_row, "heartbeat event during start of error control")) << saw_row;
  EXPECT_TRUE(has(saw_row, "no heartbeat within 500 ms after the configuration")) << saw_row;
  EXPECT_TRUE(has(saw_row, "2 ACTIVE")) << saw_row;
  EXPECT_TRUE(has(saw_row, "4210h</code> temperature")) << saw_row;
  EXPECT_TRUE(has(saw_row, "3120h</code> voltage")) << saw_row;
  EXPECT_TRUE(has(saw_row, "error register 0Dh")) << saw_row;

  const auto puller_row = row_of(page, "puller1");
  EXPECT_TRUE(has(puller_row, ">NOT HEARD<")) << puller_row;
  EXPECT_TRUE(has(puller_row, "none yet")) << puller_row;
  EXPECT_TRUE(has(puller_row, "uncertain: an EMCY 0000h left errors the register still reports")) << puller_row;

  const auto corrugator_row = row_of(page, "corrugator1");
  EXPECT_TRUE(has(corrugator_row, ">STOPPED BY THE LINE<")) << corrugator_row;
  EXPECT_TRUE(has(corrugator_row, "line hold: stopped: mandatory device saw1 lost")) << corrugator_row;
  EXPECT_TRUE(has(corrugator_row, ">stopped<")) << corrugator_row;
}

TEST(StatusPage, BusRolesAndControllerStatesInWords) {
  msg::Diagnostics d;
  d.line("demo");
  auto master = bus("a", "master");
  master.yielding_to_other_master(true);
  master.other_master_last("SYNC 080h from another master");
  d.buses().push_back(master);
  auto mastering = bus("b", "standby, mastering (took over)");
  mastering.state("bus-off");
  mastering.bus_offs(2);
  d.buses().push_back(mastering);
  auto monitor = bus("c", "monitor");
  monitor.state("error-passive");
  d.buses().push_back(monitor);
  auto master_with_sync = bus("d", "master");
  master_with_sync.sync_period_s(0.02);
  master_with_sync.sync_period_deviation_s().upper_bounds({0.0001, 0.001, 0.01});
  master_with_sync.sync_period_deviation_s().cumulative_counts({90, 100, 100});
  master_with_sync.sync_period_deviation_s().count(100);
  master_with_sync.sync_period_deviation_s().sum(0.005);
  d.buses().push_back(master_with_sync);
  const auto page = render_status_page(view_with(d));
  EXPECT_TRUE(has(page, "MASTER, YIELDING (another master is heard)")) << page;
  EXPECT_TRUE(has(page, "SYNC 080h from another master")) << page;
  EXPECT_TRUE(has(page, "MASTERING (a standby that took over)")) << page;
  EXPECT_TRUE(has(page, "<span class=\"state bad\">BUS-OFF</span>")) << page;
  EXPECT_TRUE(has(page, "bus-offs 2")) << page;
  EXPECT_TRUE(has(page, "MONITOR (listen-only)")) << page;
  EXPECT_TRUE(has(page, "ERROR-PASSIVE")) << page;
  EXPECT_TRUE(has(page, "not produced here (listen-only)")) << page;
  // 20 ms; 100 intervals, mean |deviation| 0.005 s / 100 = 0.05 ms, all within the 1 ms bound.
  EXPECT_TRUE(has(page, "every 20 ms, produced by this bridge; mean deviation 0.050 ms over 100 intervals, all "
                        "within 1 ms"))
      << page;
  EXPECT_TRUE(has(page, "12.5 %")) << page;  // bus load
  EXPECT_TRUE(has(page, "No device is configured on this bus.")) << page;
}

TEST(StatusPage, EveryStringFromTheLineFileOrTheBusIsEscaped) {
  auto d = line_of_two();
  const std::string evil = "<script>alert(\"x\")</script>&'";
  const std::string escaped = "&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt;&amp;&#39;";
  auto& saw = d.nodes()[0];
  saw.product_name(evil);  // 1008h: whatever the device says
  saw.boot_state(evil + " retry");
  saw.active_errors_known(false);
  saw.active_errors_note(evil);
  saw.boot_error().code("J");
  saw.boot_error().message(evil);
  saw.line_hold(evil);
  d.buses()[0].interface_uri(evil);
  d.buses()[0].other_master_last(evil);
  d.buses()[0].takeover(evil);
  d.buses()[0].mandatory_state(evil);
  const auto page = render_status_page(view_with(d));
  EXPECT_FALSE(has(page, "<script")) << page;
  EXPECT_FALSE(has(page, evil)) << page;
  std::size_t count = 0;
  for (auto at = page.find(escaped); at != std::string::npos; at = page.find(escaped, at + 1)) ++count;
  EXPECT_EQ(count, 9u) << page;  // each of the nine strings above, shown once, escaped
  EXPECT_EQ(lb::app::obs::html_escape("a<b>&\"c'"), "a&lt;b&gt;&amp;&quot;c&#39;");
}

TEST(StatusPage, LoadsNothingFromElsewhereAndSaysWhatItCannotTell) {
  const auto page = render_status_page(view_with(line_of_two()));
  EXPECT_FALSE(has(page, "<script")) << page;
  EXPECT_FALSE(has(page, "<link")) << page;
  EXPECT_FALSE(has(page, "src=")) << page;
  EXPECT_FALSE(has(page, "url(")) << page;
  EXPECT_FALSE(has(page, "http://")) << page;
  EXPECT_FALSE(has(page, "https://")) << page;
  EXPECT_FALSE(has(page, "@import")) << page;
  EXPECT_TRUE(has(page, "CAN is not authenticated")) << page;
  // The DDS side: connected, and its clients.
  EXPECT_TRUE(has(page, "CONNECTED")) << page;
  EXPECT_TRUE(has(page, "3 remote DDS participant(s)")) << page;
}

TEST(StatusPage, OldDiagnosticsAreShownAsStale) {
  auto v = view_with(line_of_two());
  EXPECT_FALSE(has(render_status_page(v), "STALE"));
  v.received = v.now - std::chrono::seconds(10);
  EXPECT_TRUE(has(render_status_page(v), "STALE")) << render_status_page(v);
}

TEST(StatusPage, BootErrorLettersOfCia302_2InWords) {
  using lb::app::obs::boot_error_meaning;
  EXPECT_EQ(boot_error_meaning('B'), "no answer to the device type read (1000h)");
  EXPECT_EQ(boot_error_meaning('C'), "the device type (1000h) differs from the configured one");
  EXPECT_EQ(boot_error_meaning('D'), "the vendor-ID (1018h sub 1) differs");
  EXPECT_EQ(boot_error_meaning('J'), "the configuration download failed");
  EXPECT_EQ(boot_error_meaning('M'), "the product code (1018h sub 2) differs");
  EXPECT_EQ(boot_error_meaning('N'), "the revision number (1018h sub 3) differs");
  EXPECT_EQ(boot_error_meaning('O'), "the serial number (1018h sub 4) differs");
  EXPECT_EQ(boot_error_meaning('Z'), "not a CiA 302-2 boot error letter");
}
