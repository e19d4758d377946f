// Issue 41: systemd gave the DDS unit up after 20 starts a minute (StartLimitBurst=20), and the
// supervisor of linebridge --part both restarted a DDS process that had served at once, forever.
// Both now pace the same way (docs/bus-isolation.md "Supervision"): 20 restarts a minute at once,
// then pauses of 1, 2, 4, 8, 16 and 30 s, 30 s from then on, never a stop; a DDS process that ran
// a minute ends the back-off. The figures below are those, written out.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "app/restart_pacing.hpp"

using namespace std::chrono_literals;
using lb::app::RestartPacer;
using Clock = RestartPacer::Clock;

namespace {

// A DDS process that ends `ran` after each start, started again after each pause: the pauses.
std::vector<std::chrono::milliseconds> pauses(RestartPacer& pacer, Clock::time_point& t, int starts,
                                              Clock::duration ran) {
  std::vector<std::chrono::milliseconds> out;
  for (int i = 0; i < starts; ++i) {
    pacer.started(t);
    t += ran;
    const auto p = pacer.next_pause(t);
    out.push_back(p);
    t += p;
  }
  return out;
}

}  // namespace

TEST(DdsSupervisorPacing, TwentyRestartsAMinuteAtOnceThenPausesDoublingToThirtySecondsNeverAStop) {
  RestartPacer pacer;
  auto t = Clock::now();
  // Each DDS process killed 1 s after its start, as a flood did every 1.2 s.
  const auto p = pauses(pacer, t, 40, 1s);
  for (int i = 0; i < 20; ++i) EXPECT_EQ(p[i], 0ms) << "restart " << i + 1;
  const std::vector<std::chrono::milliseconds> backoff{1s, 2s, 4s, 8s, 16s, 30s, 30s, 30s};
  for (std::size_t i = 0; i < backoff.size(); ++i) EXPECT_EQ(p[20 + i], backoff[i]) << "restart " << 21 + i;
  for (std::size_t i = 28; i < p.size(); ++i)
    EXPECT_EQ(p[i], 30s) << "restart " << i + 1 << ": never more, never a stop";
}

TEST(DdsSupervisorPacing, ADdsProcessThatRanAMinuteEndsTheBackOff) {
  RestartPacer pacer;
  auto t = Clock::now();
  pauses(pacer, t, 25, 1s);
  ASSERT_GT(pacer.step(), 0u);
  pacer.started(t);
  t += 60s;  // this one served a minute before it ended
  EXPECT_EQ(pacer.next_pause(t), 0ms);
  EXPECT_EQ(pacer.step(), 0u);
  // And the next ones are taken at once again, up to the minute's twenty.
  const auto p = pauses(pacer, t, 5, 1s);
  for (const auto pause : p) EXPECT_EQ(pause, 0ms);
}

TEST(DdsSupervisorPacing, RestartsSpreadOutAreNeverPaced) {
  RestartPacer pacer;
  auto t = Clock::now();
  // One every 3 s: twenty a minute, the most taken at once.
  for (const auto pause : pauses(pacer, t, 200, 3s)) ASSERT_EQ(pause, 0ms);
}

TEST(DdsSupervisorPacing, TheRecordBetweenProcessesKeepsThePacing) {
  RestartPacer pacer;
  auto t = Clock::now() - 30s;
  pauses(pacer, t, 23, 500ms);  // two pauses taken: 1 s, then 2 s
  ASSERT_EQ(pacer.step(), 3u);
  const auto text = pacer.record();
  auto read = RestartPacer::from_record("garbage line\n" + text + "start notanumber\n");
  EXPECT_EQ(read.step(), pacer.step());
  EXPECT_EQ(read.starts_within(t), pacer.starts_within(t));
  EXPECT_EQ(read.next_pause(t), pacer.next_pause(t));
  // A record from another boot (times ahead of this clock) is no record.
  const auto ahead = (Clock::now() + 1h).time_since_epoch().count();
  auto stale = RestartPacer::from_record("step 0\nstart " + std::to_string(ahead) + "\n");
  EXPECT_EQ(stale.starts_within(Clock::now()), 0u);
}

// The DDS process under its unit: its start waits as the record says, and adds itself to it.
TEST(DdsSupervisorPacing, AStartUnderTheUnitWaitsAsItsRecordSays) {
  const auto path = ::testing::TempDir() + "/lb_pace_" + std::to_string(::getpid());
  std::filesystem::remove(path);
  // No record yet: at once.
  auto t0 = Clock::now();
  ASSERT_TRUE(lb::app::pace_start(path));
  EXPECT_LT(Clock::now() - t0, 500ms);
  // 20 more starts in the last 2 s (21 in the minute): the next waits the first pause, 1 s.
  RestartPacer pacer;
  auto t = Clock::now() - 2s;
  for (int i = 0; i < 21; ++i) pacer.started(t + i * 90ms);
  std::ofstream(path) << pacer.record();
  t0 = Clock::now();
  ASSERT_TRUE(lb::app::pace_start(path));
  const auto waited = Clock::now() - t0;
  EXPECT_GE(waited, 950ms);
  EXPECT_LT(waited, 5s);
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  const auto after = RestartPacer::from_record(s.str());
  EXPECT_EQ(after.step(), 1u);
  EXPECT_EQ(after.starts_within(Clock::now()), 22u) << s.str();
  std::filesystem::remove(path);
}
