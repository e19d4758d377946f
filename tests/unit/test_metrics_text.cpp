// /metrics as Prometheus reads it, from a LineView built here by hand: the exact lines of the text
// exposition format (0.0.4: `name{label="value",...} value`, histograms as _bucket{le=...} with
// cumulative counts and a +Inf bucket equal to _count, then _sum and _count), and the whole
// exposition checked by the real promtool (`promtool check metrics`: the format, and Prometheus'
// naming conventions: counters end in _total, base units, help present).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include "app/observability/metrics_text.hpp"
#include "support/run_command.hpp"
#include "support/scratch_files.hpp"

namespace msg = linebridge_msgs::msg;
using lb::app::obs::LineView;
using lb::app::obs::render_metrics;

namespace {

const char* const kPromtool = "/usr/bin/promtool";

msg::NamedCount named(const std::string& name, std::uint64_t count) {
  msg::NamedCount n;
  n.name(name);
  n.count(count);
  return n;
}

msg::Histogram histogram(std::vector<double> bounds, std::vector<std::uint64_t> cumulative, std::uint64_t count,
                         double sum) {
  msg::Histogram h;
  h.upper_bounds(std::move(bounds));
  h.cumulative_counts(std::move(cumulative));
  h.count(count);
  h.sum(sum);
  return h;
}

// One bus with two devices: a saw that runs (an EMCY of each of two classes, a boot that failed
// with J once, SDO transfers measured) and a puller whose heartbeat was lost.
LineView line_view() {
  auto d = std::make_shared<msg::Diagnostics>();
  d->line("line1");
  msg::BusDiagnostics b;
  b.name("can0");
  b.interface_uri("socketcan:vcan0");
  b.role("master");
  b.state("error-passive");
  b.frames_in(1000);
  b.frames_out(500);
  b.error_frames(3);
  b.bus_offs(1);
  b.tx_error_counter(130);
  b.rx_error_counter(7);
  b.load_percent(12.5);
  b.sync_period_s(0.02);
  // 10 SYNCs: 5 within 0.1 ms of the period, 3 more within 1 ms, 1 more within 10 ms, 1 beyond.
  b.sync_period_deviation_s(histogram({0.0001, 0.001, 0.01}, {5, 8, 9}, 10, 0.0625));
  d->buses().push_back(b);

  msg::NodeDiagnostics saw;
  saw.device("saw1");
  saw.bus("can0");
  saw.node_id(5);
  saw.online(true);
  saw.nmt_state(msg::NMT_OPERATIONAL);
  saw.node_state("operational");
  saw.last_heartbeat_age_s(0.25);
  saw.boot_ups(2);
  saw.boots(3);
  saw.boot_failures(1);
  saw.boot_failures_by_letter({named("B", 0), named("J", 1), named("K", 0)});
  saw.emergencies(4);
  saw.emergencies_by_class({named("error_reset", 1), named("temperature", 3), named("device_specific", 0)});
  saw.pdos_received(200);
  saw.pdos_sent(100);
  // 4 transfers: 2 within 2 ms, 1 more within 5 ms, none more within 1 s, 1 timed out (1.001 s).
  saw.sdo_duration_s(histogram({0.002, 0.005, 1.0}, {2, 3, 3}, 4, 1.0085));
  d->nodes().push_back(saw);

  msg::NodeDiagnostics puller;
  puller.device("puller1");
  puller.bus("can0");
  puller.node_id(6);
  puller.online(false);
  puller.nmt_state(msg::NMT_UNKNOWN);
  puller.node_state("lost");
  puller.last_heartbeat_age_s(7.5);
  d->nodes().push_back(puller);

  d->dds_side().connects(2);
  d->dds_side().samples_sent(5000);
  d->dds_side().samples_replaced(40);
  d->dds_side().samples_dropped(6);
  d->commands_lost(0);

  LineView v;
  v.line = "line1";
  v.diagnostics = std::move(d);
  v.received = LineView::Clock::time_point(std::chrono::seconds(100));
  v.now = v.received + std::chrono::milliseconds(500);
  v.connected = true;
  v.samples_published = 4990;
  v.remote_participants = 2;
  return v;
}

bool has_line(const std::string& text, const std::string& line) {
  return ("\n" + text).find("\n" + line + "\n") != std::string::npos;
}

// promtool's verdict on an exposition: its exit code and what it said.
lb::test::CommandResult promtool_check(const std::string& text) {
  const auto dir = lb::test::fresh_dir("metrics-text");
  const auto file = dir + "/metrics.txt";
  std::ofstream(file) << text;
  return lb::test::run_command({"/bin/sh", "-c", std::string(kPromtool) + " check metrics < " + file});
}

}  // namespace

TEST(MetricsText, DevicesAsPrometheusNamesThem) {
  const auto text = render_metrics(line_view());
  for (
      const auto* line : {
          R"(linebridge_device_up{line="line1",bus="can0",device="saw1",node="5"} 1)",
          R"(linebridge_device_up{line="line1",bus="can0",device="puller1",node="6"} 0)",
          // An enum: every state, 1 for the current one.
          R"(linebridge_device_nmt_state{line="line1",bus="can0",device="saw1",node="5",state="operational"} 1)",
          R"(linebridge_device_nmt_state{line="line1",bus="can0",device="saw1",node="5",state="pre_operational"} 0)",
          R"(linebridge_device_nmt_state{line="line1",bus="can0",device="saw1",node="5",state="unknown"} 0)",
          R"(linebridge_device_nmt_state{line="line1",bus="can0",device="puller1",node="6",state="unknown"} 1)",
          R"(linebridge_device_node_state{line="line1",bus="can0",device="puller1",node="6",state="lost"} 1)",
          R"(linebridge_device_node_state{line="line1",bus="can0",device="puller1",node="6",state="operational"} 0)",
          R"(linebridge_device_node_state{line="line1",bus="can0",device="saw1",node="5",state="boot_failed"} 0)",
          R"(linebridge_device_last_heartbeat_age_seconds{line="line1",bus="can0",device="puller1",node="6"} 7.5)",
          R"(linebridge_device_boot_failures_total{line="line1",bus="can0",device="saw1",node="5",letter="J"} 1)",
          R"(linebridge_device_boot_failures_total{line="line1",bus="can0",device="saw1",node="5",letter="K"} 0)",
          R"(linebridge_device_emergencies_total{line="line1",bus="can0",device="saw1",node="5",class="temperature"} 3)",
          R"(linebridge_device_emergencies_total{line="line1",bus="can0",device="saw1",node="5",class="error_reset"} 1)",
          R"(linebridge_device_boot_ups_total{line="line1",bus="can0",device="saw1",node="5"} 2)",
          R"(linebridge_device_pdos_received_total{line="line1",bus="can0",device="saw1",node="5"} 200)",
          "# TYPE linebridge_device_up gauge",
          "# TYPE linebridge_device_emergencies_total counter",
          "# TYPE linebridge_device_sdo_duration_seconds histogram",
      }) {
    EXPECT_TRUE(has_line(text, line)) << "missing: " << line << "\nin:\n" << text;
  }
}

TEST(MetricsText, HistogramsHaveCumulativeBucketsAndInf) {
  const auto text = render_metrics(line_view());
  for (
      const auto* line : {
          R"(linebridge_device_sdo_duration_seconds_bucket{line="line1",bus="can0",device="saw1",node="5",le="0.002"} 2)",
          R"(linebridge_device_sdo_duration_seconds_bucket{line="line1",bus="can0",device="saw1",node="5",le="0.005"} 3)",
          R"(linebridge_device_sdo_duration_seconds_bucket{line="line1",bus="can0",device="saw1",node="5",le="1"} 3)",
          R"(linebridge_device_sdo_duration_seconds_bucket{line="line1",bus="can0",device="saw1",node="5",le="+Inf"} 4)",
          R"(linebridge_device_sdo_duration_seconds_count{line="line1",bus="can0",device="saw1",node="5"} 4)",
          R"(linebridge_device_sdo_duration_seconds_sum{line="line1",bus="can0",device="saw1",node="5"} 1.0085)",
          R"(linebridge_bus_sync_period_deviation_seconds_bucket{line="line1",bus="can0",le="0.0001"} 5)",
          R"(linebridge_bus_sync_period_deviation_seconds_bucket{line="line1",bus="can0",le="0.01"} 9)",
          R"(linebridge_bus_sync_period_deviation_seconds_bucket{line="line1",bus="can0",le="+Inf"} 10)",
          R"(linebridge_bus_sync_period_deviation_seconds_sum{line="line1",bus="can0"} 0.0625)",
      }) {
    EXPECT_TRUE(has_line(text, line)) << "missing: " << line << "\nin:\n" << text;
  }
  // A device without SDO measurements (no bounds: the bridge does not master its bus) has none.
  EXPECT_EQ(text.find(R"(linebridge_device_sdo_duration_seconds_count{line="line1",bus="can0",device="puller1")"),
            std::string::npos);
}

TEST(MetricsText, BusAndDdsSideInBaseUnits) {
  const auto text = render_metrics(line_view());
  for (const auto* line : {
           R"(linebridge_bus_state{line="line1",bus="can0",state="error_passive"} 1)",
           R"(linebridge_bus_state{line="line1",bus="can0",state="bus_off"} 0)",
           R"(linebridge_bus_frames_received_total{line="line1",bus="can0"} 1000)",
           R"(linebridge_bus_frames_transmitted_total{line="line1",bus="can0"} 500)",
           R"(linebridge_bus_error_frames_total{line="line1",bus="can0"} 3)",
           R"(linebridge_bus_off_entries_total{line="line1",bus="can0"} 1)",
           R"(linebridge_bus_controller_tx_errors{line="line1",bus="can0"} 130)",
           R"(linebridge_bus_controller_rx_errors{line="line1",bus="can0"} 7)",
           // 12.5 % as a ratio; 20 ms in seconds.
           R"(linebridge_bus_load_ratio{line="line1",bus="can0"} 0.125)",
           R"(linebridge_bus_sync_period_seconds{line="line1",bus="can0"} 0.02)",
           R"(linebridge_bus_info{line="line1",bus="can0",interface="socketcan:vcan0",role="master"} 1)",
           R"(linebridge_dds_side_connected{line="line1"} 1)",
           R"(linebridge_dds_side_connects_total{line="line1"} 2)",
           R"(linebridge_dds_samples_sent_total{line="line1"} 5000)",
           R"(linebridge_dds_samples_replaced_total{line="line1"} 40)",
           R"(linebridge_dds_samples_dropped_total{line="line1"} 6)",
           R"(linebridge_dds_samples_published_total{line="line1"} 4990)",
           R"(linebridge_dds_remote_participants{line="line1"} 2)",
           R"(linebridge_diagnostics_age_seconds{line="line1"} 0.5)",
       }) {
    EXPECT_TRUE(has_line(text, line)) << "missing: " << line << "\nin:\n" << text;
  }
  EXPECT_NE(text.find("linebridge_build_info{line=\"line1\",version=\""), std::string::npos) << text;
}

TEST(MetricsText, AStateOutsideTheKnownSetIsItsOwnSeries) {
  auto view = line_view();
  auto d = std::make_shared<msg::Diagnostics>(*view.diagnostics);
  d->nodes()[0].node_state("Some New-State");
  view.diagnostics = d;
  const auto text = render_metrics(view);
  EXPECT_TRUE(has_line(
      text, R"(linebridge_device_node_state{line="line1",bus="can0",device="saw1",node="5",state="some_new_state"} 1)"))
      << text;
  EXPECT_TRUE(
      has_line(text,
               R"(linebridge_device_node_state{line="line1",bus="can0",device="saw1",node="5",state="operational"} 0)"))
      << text;
}

// A device on a monitor bus is "monitored" and nothing else: not ten master states at 0 each.
TEST(MetricsText, AMonitoredDeviceHasItsOneState) {
  auto view = line_view();
  auto d = std::make_shared<msg::Diagnostics>(*view.diagnostics);
  d->nodes()[1].node_state("monitored");
  view.diagnostics = d;
  const auto text = render_metrics(view);
  const std::string series = R"(linebridge_device_node_state{line="line1",bus="can0",device="puller1",node="6",)";
  EXPECT_TRUE(has_line(text, series + R"(state="monitored"} 1)")) << text;
  std::size_t count = 0;
  for (auto at = text.find(series); at != std::string::npos; at = text.find(series, at + 1)) ++count;
  EXPECT_EQ(count, 1u) << text;
  EXPECT_TRUE(
      has_line(text, R"(linebridge_device_node_state{line="line1",bus="can0",device="saw1",node="5",state="lost"} 0)"))
      << "the master's devices keep every state\n"
      << text;
}

TEST(MetricsText, BeforeTheFirstDiagnosticsOnlyTheProcessItself) {
  LineView v;
  v.line = "line1";
  const auto text = render_metrics(v);
  EXPECT_TRUE(has_line(text, R"(linebridge_dds_side_connected{line="line1"} 0)")) << text;
  EXPECT_EQ(text.find("linebridge_device_"), std::string::npos) << text;
  EXPECT_EQ(text.find("linebridge_bus_"), std::string::npos) << text;
  EXPECT_EQ(text.find("linebridge_diagnostics_age_seconds"), std::string::npos) << text;
}

TEST(MetricsText, PromtoolAcceptsTheExposition) {
  if (!std::filesystem::exists(kPromtool)) GTEST_SKIP() << kPromtool << " absent (Debian package prometheus)";
  LineView empty;
  empty.line = "line1";
  for (const auto& view : {line_view(), empty}) {
    const auto text = render_metrics(view);
    const auto r = promtool_check(text);
    EXPECT_EQ(r.exit_code, 0) << r.output << "\n" << text;
    // promtool prints its lint findings (naming, units) and exits 0 on some of them: none wanted.
    EXPECT_EQ(r.output, "") << text;
  }
}

TEST(MetricsText, PromtoolCatchesWhatItIsTrustedToCatch) {
  if (!std::filesystem::exists(kPromtool)) GTEST_SKIP() << kPromtool << " absent (Debian package prometheus)";
  // The check above would pass an exposition promtool does not read: it must fail a counter
  // without _total and a broken line, or it proves nothing.
  const auto bad_name = promtool_check("# HELP x_frames A count.\n# TYPE x_frames counter\nx_frames 1\n");
  EXPECT_NE(bad_name.output, "") << "promtool said nothing of a counter without _total";
  const auto broken = promtool_check("# TYPE x gauge\nx{a=\"1\" 1\n");
  EXPECT_NE(broken.exit_code, 0) << broken.output;
}
