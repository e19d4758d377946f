// /metrics as a plant's monitoring reads it (issue 43): a saw line (the real bridge, --part both,
// and the real simulator on a virtual bus) with its observability listener on a free loopback
// port, scraped every second by a real Prometheus server, and asked in PromQL over Prometheus'
// HTTP API: the saw is up; an EMCY the simulator sends (its error simulation 2003h raises 4210h,
// temperature: CiA 301) is counted in its class; every query of the Grafana dashboard
// (packaging/grafana/linebridge.json) is accepted and finds data; once the simulator is killed the
// saw is down (its heartbeat lost). Each query and Prometheus' answer are printed.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "msgs/sawPubSubTypes.h"
#include "support/line_harness.hpp"
#include "support/prometheus_server.hpp"
#include "support/scratch_files.hpp"

namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using lb::test::PromAnswer;
using lb::test::PrometheusServer;

namespace {

constexpr std::uint16_t kErrorSimulation = 0x2003;  // the simulator's: writing a code raises it as an EMCY
constexpr std::uint64_t kTemperature = 0x4210;      // CiA 301: 4xxxh temperature

// Polls the query until its answer has exactly `expected` as its one value (or the deadline).
PromAnswer wait_for_value(PrometheusServer& prom, const std::string& query, const std::string& expected,
                          std::chrono::seconds deadline = 60s) {
  PromAnswer last;
  lb::test::eventually(deadline, [&] {
    last = prom.query(query);
    return last.success && last.values == std::vector<std::string>{expected};
  });
  std::cout << "[ promql ] " << query << "\n[ answer ] " << last.json << std::endl;
  return last;
}

// Every "expr" of a Grafana dashboard, JSON strings unescaped.
std::vector<std::string> dashboard_queries(const std::string& json) {
  std::vector<std::string> out;
  const std::string key = "\"expr\": \"";
  for (auto at = json.find(key); at != std::string::npos; at = json.find(key, at + 1)) {
    std::string expr;
    for (auto i = at + key.size(); i < json.size() && json[i] != '"'; ++i) {
      if (json[i] == '\\' && i + 1 < json.size()) ++i;
      expr.push_back(json[i]);
    }
    out.push_back(expr);
  }
  return out;
}

// Grafana's variables as Prometheus would get them with every line, bus and device selected.
std::string as_grafana_sends_it(std::string expr) {
  const std::vector<std::pair<std::string, std::string>> variables = {
      {"$__rate_interval", "1m"}, {"$__range", "5m"}, {"$line", ".*"}, {"$bus", ".*"}, {"$device", ".*"}};
  for (const auto& [name, value] : variables) {
    for (auto at = expr.find(name); at != std::string::npos; at = expr.find(name, at + value.size()))
      expr.replace(at, name.size(), value);
  }
  return expr;
}

}  // namespace

TEST(ObservabilityMetrics, PrometheusSeesTheSawUpItsEmcyAndItsHeartbeatLost) {
  if (!std::filesystem::exists(lb::test::kPrometheus))
    GTEST_SKIP() << lb::test::kPrometheus << " absent (Debian package prometheus)";
  const auto port = lb::test::free_loopback_port();
  const auto target = "127.0.0.1:" + std::to_string(port);
  lb::test::LineHarness line("obsmetrics", 43);
  line.start("  - {name: saw1, bus: b, node_id: 5, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 400}\n", "",
             "", "observability: {listen: '" + target + "'}\n");
  auto status = line.operational_status<msg::SawStatusPubSubType>("saw1");
  ASSERT_TRUE(lb::test::eventually(30s, [&] { return lb::test::http_get(port, "/metrics").status == 200; }))
      << "no /metrics on " << target << "\n"
      << line.logs();

  PrometheusServer prom({target});
  ASSERT_TRUE(prom.wait_ready()) << prom.log();
  const auto saw = std::string(R"(line="obsmetrics",device="saw1")");

  const auto up = wait_for_value(prom, "linebridge_device_up{" + saw + "}", "1");
  ASSERT_EQ(up.values, std::vector<std::string>{"1"}) << up.error << "\n" << prom.log() << line.logs();
  const auto operational = wait_for_value(prom, "linebridge_device_nmt_state{" + saw + R"(,state="operational"})", "1");
  EXPECT_EQ(operational.values, std::vector<std::string>{"1"}) << operational.error;
  // The bridge masters the bus: its SYNC is measured (a count of intervals, not yet a judgement).
  const auto syncs = prom.query(R"(linebridge_bus_sync_period_deviation_seconds_count{line="obsmetrics",bus="b"} > 0)");
  std::cout << "[ promql ] linebridge_bus_sync_period_deviation_seconds_count > 0\n[ answer ] " << syncs.json
            << std::endl;
  EXPECT_EQ(syncs.values.size(), 1u) << syncs.json;

  // The EMCY: none of its class before, one after the simulator sent it.
  const auto emcys = "linebridge_device_emergencies_total{" + saw + R"(,class="temperature"})";
  const auto before = wait_for_value(prom, emcys, "0");
  ASSERT_EQ(before.values, std::vector<std::string>{"0"}) << before.error;
  ASSERT_TRUE(line.sdo_write("saw1", kErrorSimulation, 0, "UNSIGNED32", kTemperature).success()) << line.logs();
  const auto after = wait_for_value(prom, emcys, "1");
  EXPECT_EQ(after.values, std::vector<std::string>{"1"}) << after.error << "\n" << line.logs();

  // Every query of the dashboard, as Grafana sends it with all selected: accepted, and with data
  // (a name that no longer exists would answer an empty vector). rate() over 1m needs 2 scrapes.
  ASSERT_TRUE(lb::test::eventually(60s, [&] {
    const auto scrapes = prom.query(R"(count_over_time(linebridge_build_info{line="obsmetrics"}[1m]) >= 3)");
    return scrapes.values.size() == 1;
  }));
  const auto queries = dashboard_queries(
      lb::test::read_text(std::string(LB_SOURCE_DIR) + "/packaging/grafana/linebridge.json"));
  ASSERT_GE(queries.size(), 20u) << "the dashboard's queries were not found";
  for (const auto& q : queries) {
    const auto promql = as_grafana_sends_it(q);
    ASSERT_EQ(promql.find('$'), std::string::npos) << "a Grafana variable left in: " << promql;
    const auto a = prom.query(promql);
    EXPECT_TRUE(a.success) << promql << ": " << a.error;
    EXPECT_FALSE(a.values.empty()) << promql << ": no data\n" << a.json;
  }

  // The simulator dies: no heartbeat within 400 ms, the saw is down and lost.
  line.sim().stop();
  const auto down = wait_for_value(prom, "linebridge_device_up{" + saw + "}", "0");
  EXPECT_EQ(down.values, std::vector<std::string>{"0"}) << down.error << "\n" << line.logs();
  const auto lost = wait_for_value(prom, "linebridge_device_node_state{" + saw + R"(,state="lost"})", "1");
  EXPECT_EQ(lost.values, std::vector<std::string>{"1"}) << lost.error;
  EXPECT_TRUE(prom.process().running()) << prom.log();
}
