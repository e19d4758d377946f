// The secured demo as a new user runs it (launch_scripts/demo.sh --secure), ten times in a row: it
// failed 1 run of 8 when `linebridge-cli set` sent its set value as soon as the saw was online,
// 14 ms before the saw's boot passed (refused: it would enable a device not yet configured).
// Every run must set the saw's values, show what the demo shows, say DDS Security's expected
// "No key material yet" at most once, and stop cleanly. Each run is
// bounded at 120 s (about 25 s each on an idle machine); the test at 600 s (tests/CMakeLists.txt).
// The test runs inside launch_scripts/netns-run.sh (ctest), so the demo is run with --inside: its
// processes stay in the test's private namespace, and nothing is built or installed.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "support/run_command.hpp"

namespace {

bool has(const std::string& text, const std::string& what) { return text.find(what) != std::string::npos; }

TEST(Demo, SecuredDemoRunsTenTimesInARow) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const auto bin = std::filesystem::path(LB_BIN_BRIDGE).parent_path().string();
  const auto demo = std::string(LB_SOURCE_DIR) + "/launch_scripts/demo.sh";
  for (int run = 1; run <= 10; ++run) {
    const auto r = lb::test::run_command({"/usr/bin/env", "LINEBRIDGE_BIN=" + bin, demo, "--inside", "--secure",
                                          "--duration", "1"},
                                         std::chrono::seconds(120));
    const auto& out = r.output;
    ASSERT_EQ(r.exit_code, 0) << "run " << run << " of 10\n" << out;
    EXPECT_TRUE(has(out, "saw1: accepted: program on, ")) << "run " << run << ": the first set value\n" << out;
    EXPECT_TRUE(has(out, "product length 0.4 m")) << "run " << run << ": the new product length\n" << out;
    EXPECT_TRUE(has(out, "saw1: set value refused")) << "run " << run << ": 120 % refused\n" << out;
    EXPECT_TRUE(has(out, "--join")) << "run " << run << ": how to join the demo's namespace\n" << out;
    // A clean stop reads clean: no client waiting for a bridge that stopped under it, no DDS
    // process reported lost.
    EXPECT_TRUE(has(out, "demo: stopped cleanly")) << "run " << run << "\n" << out;
    EXPECT_FALSE(has(out, "DDS side gone")) << "run " << run << "\n" << out;
    const auto tail = out.substr(
        out.rfind("(nothing received)") == std::string::npos ? 0 : out.rfind("(nothing received)"));
    EXPECT_FALSE(has(tail, "waiting for the bridge")) << "run " << run << ": after the demo's last step\n" << out;
    // Fast DDS's "No key material yet" (a participant just discovered whose keys are still being
    // exchanged: expected at every client's first call) is said once, as what it is, not a
    // warning per dropped submessage (104-109 lines a run before).
    std::size_t key_material = 0;
    for (auto at = out.find("key material"); at != std::string::npos; at = out.find("key material", at + 1))
      ++key_material;
    EXPECT_LE(key_material, 1u) << "run " << run << "\n" << out;
    if (::testing::Test::HasFailure()) break;  // one failed run says it all; the rest would repeat it
  }
}

}  // namespace
