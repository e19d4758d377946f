// The alert rules shipped in packaging/prometheus/linebridge-rules.yml, checked by the real
// promtool (Debian package prometheus): `check rules` (syntax, PromQL, templates) and `test rules`
// against series written by hand (tests/prometheus/linebridge-rules-test.yml: when each alert
// fires, with which labels and text, and when it does not).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "support/run_command.hpp"
#include "support/scratch_files.hpp"

namespace {

const std::string kPromtool = "/usr/bin/promtool";
const std::string kRules = std::string(LB_SOURCE_DIR) + "/packaging/prometheus/linebridge-rules.yml";
const std::string kRuleTests = std::string(LB_SOURCE_DIR) + "/tests/prometheus/linebridge-rules-test.yml";

bool has(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

}  // namespace

TEST(AlertRules, PromtoolChecksThem) {
  if (!std::filesystem::exists(kPromtool)) GTEST_SKIP() << kPromtool << " absent (Debian package prometheus)";
  const auto r = lb::test::run_command({kPromtool, "check", "rules", kRules});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r.output, "SUCCESS: 6 rules found")) << r.output;
}

TEST(AlertRules, FireWhenAndOnlyWhenTheSeriesWrittenByHandSay) {
  if (!std::filesystem::exists(kPromtool)) GTEST_SKIP() << kPromtool << " absent (Debian package prometheus)";
  const auto r = lb::test::run_command({kPromtool, "test", "rules", kRuleTests});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r.output, "SUCCESS")) << r.output;
}

// The test above proves something only if promtool fails a wrong expectation: the same tests with
// the device-down alert expected silent while saw1 is down must fail, and say so.
TEST(AlertRules, AWrongExpectationFails) {
  if (!std::filesystem::exists(kPromtool)) GTEST_SKIP() << kPromtool << " absent (Debian package prometheus)";
  auto text = lb::test::read_text(kRuleTests);
  const std::string firing = "      - eval_time: 75s\n        alertname: LinebridgeDeviceDown\n        exp_alerts:\n";
  const auto at = text.find(firing);
  ASSERT_NE(at, std::string::npos) << "the device-down case is not where this test expects it";
  text.replace(at, firing.size(),
               "      - eval_time: 75s\n        alertname: LinebridgeDeviceDown\n        exp_alerts: []\n"
               "      - eval_time: 76s\n        alertname: LinebridgeDeviceDown\n        exp_alerts:\n");
  const auto dir = lb::test::fresh_dir("alert-rules");
  std::filesystem::create_directories(dir + "/tests/prometheus");
  std::filesystem::create_directories(dir + "/packaging/prometheus");
  std::filesystem::copy_file(kRules, dir + "/packaging/prometheus/linebridge-rules.yml");
  const auto tests = dir + "/tests/prometheus/linebridge-rules-test.yml";
  std::ofstream(tests) << text;
  const auto r = lb::test::run_command({kPromtool, "test", "rules", tests});
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r.output, "alertname: LinebridgeDeviceDown, time: 1m15s")) << r.output;
}
