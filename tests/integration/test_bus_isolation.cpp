// Issue 25: the line never depends on its DDS side. The bridge runs as two processes (linebridge's
// default, --part both: the bus process starts its DDS process and replaces it when it dies).
// Under load (a saw at 20 ms SYNC, status on DDS at every cycle) the DDS process is killed with
// SIGKILL at 20 random moments; what counts is on the bus (every SYNC, every RPDO1, every
// heartbeat, with their stamps) and on DDS (a new DDS process publishing again).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/types.h>
#include <unistd.h>

#include <dirent.h>
#include <sys/stat.h>
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>

#include "dds/participant.hpp"
#include "dds/topic_names.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/bus_spy.hpp"
#include "support/child_process.hpp"
#include "support/line_harness.hpp"
#include "support/run_command.hpp"
#include "support/sanitized.hpp"
#include "support/saw_setpoints.hpp"
#include "support/simulated_saw.hpp"

using namespace std::chrono_literals;
namespace msg = linebridge_msgs::msg;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::uint32_t kNode = 5;
constexpr int kKills = 20;
constexpr std::int64_t kSyncPeriodNs = 20'000'000;

// Under the sanitizers (test.sh's stages 1 and 3) every process of the line runs several times
// slower: there the test asks that SYNC never stops and the DDS process comes back, not the
// figures of issue 25, which the normal build (stage 4) holds to.
using lb::test::kSanitized;
// No SYNC missed: a gap of two periods is one missing (sanitized: no stop, 250 ms).
constexpr std::int64_t kWidestSyncGapNs = kSanitized ? 250'000'000 : 2 * kSyncPeriodNs;
// A new DDS process's first status sample at this test's subscriber after each kill (sanitized:
// 10 s). The DDS process itself is ready within 0.1 s of the kill (its log); the rest is Fast DDS
// discovery between it and this subscriber, whose resends put one kill in 20 near 1 s (measured:
// p50 90 ms, max 985 ms), so the bound is 2 s and the distribution is printed.
constexpr double kBackWithinMs = kSanitized ? 10'000.0 : 2'000.0;

using lb::test::children_of;

struct Seen {
  std::mutex m;
  std::condition_variable cv;
  struct Status {
    Clock::time_point at;
    std::array<std::uint8_t, 12> writer{};
  };
  std::vector<Status> status;
  msg::Diagnostics diagnostics;
  template <class Pred>
  bool wait(Clock::duration timeout, Pred pred) {
    std::unique_lock lock(m);
    return cv.wait_for(lock, timeout, pred);
  }
};

}  // namespace

class BusIsolation : public ::testing::Test {
 protected:
  void SetUp() override { start_line(bridge_launcher()); }

  // How the bridge is started: linebridge --part both (the default) with a short alarm for a
  // missing DDS side (its own arguments come after the line file's: sh appends them).
  virtual std::vector<std::string> bridge_launcher() {
    return {"/bin/sh", "-c", "exec \"$0\" \"$@\" --dds-absent-alarm 1"};
  }

  void start_line(std::vector<std::string> launcher) {
    ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
    line_.set_bridge_launcher(std::move(launcher));
    line_.start(lb::test::simulated_saw("b"), "", ", role: master, sync_period_ms: 20, realtime_priority: 20");
    const auto topic = [](const char* t) { return lb::ddsl::topic_name("iso", "saw1", t); };
    ASSERT_TRUE(line_.dds().subscribe<msg::SawStatusPubSubType>(
        topic("status"), lb::ddsl::QosKind::state,
        [this](const msg::SawStatus&, const eprosima::fastdds::dds::SampleInfo& info) {
          std::lock_guard lock(seen_.m);
          Seen::Status s{Clock::now(), {}};
          std::copy(std::begin(info.sample_identity.writer_guid().guidPrefix.value),
                    std::end(info.sample_identity.writer_guid().guidPrefix.value), s.writer.begin());
          seen_.status.push_back(s);
          seen_.cv.notify_all();
        },
        1000));
    ASSERT_TRUE(line_.dds().subscribe<msg::DiagnosticsPubSubType>(
        lb::ddsl::topic_name("iso", lb::ddsl::kBridgeNamespace, "diagnostics"), lb::ddsl::QosKind::state,
        [this](const msg::Diagnostics& d, const auto&) {
          std::lock_guard lock(seen_.m);
          seen_.diagnostics = d;
          seen_.cv.notify_all();
        }));
    ASSERT_TRUE(setpoints_.open(line_.dds(), "iso", "saw1"));
  }

  void TearDown() override {
    if (line_.started()) {
      EXPECT_EQ(line_.bridge().stop(), 0) << "the bridge did not exit cleanly on SIGTERM\n" << logs();
    }
  }

  std::string logs() const { return line_.logs(); }

  void write(std::uint32_t request_id, double percent, double length_m) {
    ASSERT_TRUE(setpoints_.write(request_id, true, percent, length_m));
  }

  // The saw operational and a set value in force (RPDO1 bytes from CiA 420-4 by hand, as in
  // SawLine: control word 0005h, 50.00 % = 1388h, 0.5 m = 1388h in 0.1 mm); `request` is the last
  // request id written.
  static constexpr std::array<std::uint8_t, 8> kInForce{0x05, 0x00, 0x88, 0x13, 0x88, 0x13, 0x00, 0x00};
  void put_set_value_in_force(std::uint32_t& request) {
    ASSERT_TRUE(seen_.wait(30s, [&] { return !seen_.status.empty(); })) << logs();
    ASSERT_TRUE(setpoints_.wait_matched(20s)) << logs();
    bool accepted = false;
    // A set value that enables the saw is refused until its boot passed: wait for the saw's
    // operational heartbeat (CiA 301: 700h + node, state 05h) on the bus, then ask again on each
    // refusal until a deadline.
    const auto accept_deadline = Clock::now() + 60s;
    bool operational = false;
    while (!operational && Clock::now() < accept_deadline) {
      const auto hb = line_.spy().frames(0x700 + kNode);
      operational = !hb.empty() && hb.back().len == 1 && hb.back().data[0] == 0x05;
      if (!operational) std::this_thread::sleep_for(20ms);
    }
    ASSERT_TRUE(operational) << logs();
    while (!accepted && Clock::now() < accept_deadline) {
      write(++request, 50.0, 0.5);
      const auto answer = setpoints_.answer(request, 2s);
      accepted = answer && answer->accepted();
    }
    ASSERT_TRUE(accepted) << logs();
    const auto on_bus_deadline = Clock::now() + 10s;
    bool on_bus = false;
    while (!on_bus && Clock::now() < on_bus_deadline) {
      const auto f = line_.spy().frames(0x200 + kNode);
      on_bus = !f.empty() && f.back().data == kInForce;
      if (!on_bus) std::this_thread::sleep_for(20ms);
    }
    ASSERT_TRUE(on_bus) << "RPDO1 with the set value never on the bus\n" << logs();
  }

  Seen seen_;  // before line_: its participant (and every listener call) goes first
  lb::test::SawSetpoints setpoints_;
  lb::test::LineHarness line_{"iso", 11};
};

TEST_F(BusIsolation, KillingTheDdsProcessTwentyTimesChangesNothingOnTheBus) {
  std::uint32_t request = 1;
  ASSERT_NO_FATAL_FAILURE(put_set_value_in_force(request));
  line_.spy().clear();  // from here on every frame is checked

  std::mt19937 rng(std::random_device{}());
  std::uniform_int_distribution<int> pause_ms(50, 800);
  std::vector<double> back_ms;
  std::vector<std::uint32_t> written_while_down;
  for (int kill = 0; kill < kKills; ++kill) {
    std::vector<pid_t> children;
    const auto child_deadline = Clock::now() + 20s;
    while ((children = children_of(line_.bridge().pid())).size() != 1 && Clock::now() < child_deadline) {
      std::this_thread::sleep_for(10ms);
    }
    ASSERT_EQ(children.size(), 1u) << "the bridge has no DDS process (kill " << kill << ")\n" << logs();
    std::this_thread::sleep_for(std::chrono::milliseconds(pause_ms(rng)));
    std::array<std::uint8_t, 12> old_writer{};
    {
      std::lock_guard lock(seen_.m);
      ASSERT_FALSE(seen_.status.empty());
      old_writer = seen_.status.back().writer;
    }
    ASSERT_EQ(::kill(children[0], SIGKILL), 0);
    const auto killed_at = Clock::now();
    // A set value while the DDS process is down: no DDS side to take it, so no answer, and never
    // applied later (checked on the bus below: every RPDO1 keeps the value in force).
    write(++request, 80.0, 0.7);
    written_while_down.push_back(request);
    ASSERT_TRUE(seen_.wait(20s,
                           [&] {
                             return !seen_.status.empty() && seen_.status.back().writer != old_writer &&
                                    seen_.status.back().at > killed_at;
                           }))
        << "no status from a new DDS process after kill " << kill << "\n"
        << logs();
    std::lock_guard lock(seen_.m);
    const auto first_new = std::find_if(seen_.status.begin(), seen_.status.end(), [&](const Seen::Status& s) {
      return s.at > killed_at && s.writer != old_writer;
    });
    back_ms.push_back(std::chrono::duration<double, std::milli>(first_new->at - killed_at).count());
  }

  // On DDS: the bus process counted every DDS process that connected (diagnostics, republished by each).
  EXPECT_TRUE(seen_.wait(20s, [&] { return seen_.diagnostics.dds_side().connects() >= kKills + 1; }))
      << "connects " << seen_.diagnostics.dds_side().connects() << "\n"
      << logs();
  const auto results = setpoints_.results().samples();
  for (const auto r : written_while_down) {
    EXPECT_FALSE(std::any_of(results.begin(), results.end(), [r](const msg::SetpointResult& a) {
      return a.request_id() == r;
    })) << "a set value written while the DDS side was down was answered";
  }

  // On the bus, over the whole run.
  const auto sync = line_.spy().frames(0x80);
  ASSERT_GT(sync.size(), 100u);
  std::int64_t widest = 0;
  for (std::size_t i = 1; i < sync.size(); ++i)
    widest = std::max(widest, sync[i].timestamp_ns - sync[i - 1].timestamp_ns);
  const auto rpdos = line_.spy().frames(0x200 + kNode);
  ASSERT_GT(rpdos.size(), 100u);
  std::size_t other_rpdos = 0;
  for (const auto& f : rpdos) other_rpdos += f.data != kInForce ? 1 : 0;
  std::size_t not_operational = 0;
  const auto heartbeats = line_.spy().frames(0x700 + kNode);
  for (const auto& f : heartbeats) not_operational += (f.len != 1 || f.data[0] != 0x05) ? 1 : 0;

  std::sort(back_ms.begin(), back_ms.end());
  std::ostringstream summary;
  summary << "kills=" << kKills << " sync_frames=" << sync.size() << " widest_sync_gap_ms=" << widest / 1e6
          << " rpdo1_frames=" << rpdos.size() << " heartbeats=" << heartbeats.size()
          << " back_ms p50=" << back_ms[back_ms.size() / 2] << " max=" << back_ms.back();
  std::cout << summary.str() << "\n";
  RecordProperty("summary", summary.str());
  EXPECT_EQ(other_rpdos, 0u) << "RPDO1 changed while the DDS process was killed";
  EXPECT_EQ(not_operational, 0u) << "the saw left operational";
  EXPECT_GT(heartbeats.size(), 20u);
  // No SYNC missed (the bus loop at realtime priority, as the packaged unit allows).
  EXPECT_LT(widest, kWidestSyncGapNs) << summary.str();
  // A new DDS process publishing, as a subscriber sees it, after every kill.
  EXPECT_LT(back_ms.back(), kBackWithinMs) << summary.str();
  if (!kSanitized) {
    EXPECT_LT(back_ms[back_ms.size() / 2], 1000.0) << summary.str();
  }
  EXPECT_TRUE(line_.bridge().running()) << logs();
}

// Issue 27: a device's set values reach its bus loop on that bus's own lane, not through the
// channel's thread (docs/bus-isolation.md). The bus process counts what it handed to a reader on
// its lane and publishes the count (diagnostics, dds_side.samples_on_lanes): every set value the
// saw accepted came that way, and nothing is counted twice. A bridge whose DDS side sent set
// values on the channel would pass every other test here and fail this one.
TEST_F(BusIsolation, EverySetValueReachesItsBusLoopOnTheBussLane) {
  std::uint32_t request = 1;
  ASSERT_NO_FATAL_FAILURE(put_set_value_in_force(request));
  for (int i = 1; i <= 5; ++i) {
    write(++request, 50.0 + i, 0.5);
    const auto answer = setpoints_.answer(request, 10s);
    ASSERT_TRUE(answer && answer->accepted()) << "set value " << request << " not accepted\n" << logs();
  }
  std::size_t accepted = 0;
  for (const auto& r : setpoints_.results().samples()) accepted += r.accepted() ? 1 : 0;
  const std::uint64_t written = request - 1;  // request ids 2 .. request
  ASSERT_GE(accepted, 6u);
  std::uint64_t on_lanes = 0;
  EXPECT_TRUE(seen_.wait(20s,
                         [&] {
                           on_lanes = seen_.diagnostics.dds_side().samples_on_lanes();
                           return on_lanes >= accepted;
                         }))
      << "set values taken on a lane: " << on_lanes << ", accepted: " << accepted << "\n"
      << logs();
  EXPECT_LE(on_lanes, written) << "more samples on the lane than set values written";
}

namespace {

std::int64_t widest_gap_ns(const std::vector<lb::can::CanFrame>& frames) {
  std::int64_t widest = 0;
  for (std::size_t i = 1; i < frames.size(); ++i)
    widest = std::max(widest, frames[i].timestamp_ns - frames[i - 1].timestamp_ns);
  return widest;
}

std::size_t count_of(const std::string& text, const std::string& what) {
  std::size_t n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + what.size())) ++n;
  return n;
}

template <class Pred>
bool eventually(Clock::duration timeout, Pred pred) {
  const auto deadline = Clock::now() + timeout;
  while (!pred()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(20ms);
  }
  return true;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

// Issue 41: a DDS process that refused the configuration after one had served (a certificate, a
// grant or a CRL that expired since, found at a restart) ended linebridge --part both with exit 2,
// and the line's SYNC with it. Now the bus runs on, the reason is said (the log at once, the
// diagnostics once a DDS side is back), the refusing DDS process is tried again with the back-off,
// and once the file is right a DDS process serves again, without a restart of the bus process.
TEST_F(BusIsolation, ADdsProcessThatRefusesTheConfigurationAfterOneServedNeverStopsTheBus) {
  std::uint32_t request = 1;
  ASSERT_NO_FATAL_FAILURE(put_set_value_in_force(request));
  const auto config = line_.bridge_config();
  const auto original = read_file(config);
  ASSERT_NE(original.find("line: iso\n"), std::string::npos);
  // The bus process read its file at its start; every DDS process reads it at its own, and one
  // configured for another line refuses the bus side's (exit 2), as it refuses an expired
  // certificate: a refusal of the configuration, found after a DDS process served.
  auto other = original;
  other.replace(other.find("line: iso\n"), 10, "line: other\n");
  { std::ofstream(config) << other; }
  line_.spy().clear();
  const auto children = children_of(line_.bridge().pid());
  ASSERT_EQ(children.size(), 1u) << logs();
  ASSERT_EQ(::kill(children[0], SIGKILL), 0);
  // Refused, and refused again after the back-off's pause: the bus process runs on.
  ASSERT_TRUE(eventually(30s, [&] { return count_of(line_.bridge().log(), "exited with 2") >= 2; })) << logs();
  EXPECT_TRUE(line_.bridge().running()) << logs();
  EXPECT_NE(line_.bridge().log().find("the bus runs on without DDS"), std::string::npos) << logs();
  // The alarm (1 s here) in the bus process's log.
  ASSERT_TRUE(line_.bridge().wait_log("no DDS side for", 20s)) << logs();

  const auto restored = Clock::now();
  { std::ofstream(config) << original; }
  ASSERT_TRUE(seen_.wait(30s, [&] { return !seen_.status.empty() && seen_.status.back().at > restored; }))
      << "no DDS process served again once the line file was right\n"
      << logs();
  // What the returning DDS side publishes says what happened meanwhile.
  EXPECT_TRUE(seen_.wait(20s,
                         [&] {
                           const auto& side = seen_.diagnostics.dds_side();
                           return side.connected() && side.absent_alarms() >= 1 &&
                                  side.last_end().find("exited with 2") != std::string::npos;
                         }))
      << "dds_side: connected " << seen_.diagnostics.dds_side().connected() << " absent_alarms "
      << seen_.diagnostics.dds_side().absent_alarms() << " last_end '" << seen_.diagnostics.dds_side().last_end()
      << "'\n"
      << logs();

  const auto sync = line_.spy().frames(0x80);
  ASSERT_GT(sync.size(), 100u);
  EXPECT_LT(widest_gap_ns(sync), kWidestSyncGapNs) << "SYNC gapped while the DDS side refused";
  std::size_t other_rpdos = 0;
  for (const auto& f : line_.spy().frames(0x200 + kNode)) other_rpdos += f.data != kInForce ? 1 : 0;
  EXPECT_EQ(other_rpdos, 0u);
  EXPECT_TRUE(line_.bridge().running()) << logs();
}

// Issue 41: under linebridge --part both a DDS process that had served was replaced at once
// however often it died, where systemd gave the unit up after 20 starts a minute. Both now pace
// alike: 20 restarts a minute at once, then pauses of 1, 2, 4, 8 s ... (at most 30 s), never a
// stop. Each DDS process here is killed once it is connected (served), as a flood ended them.
TEST_F(BusIsolation, ADdsProcessKilledAgainAndAgainIsRestartedWithABackOffNeverGivenUp) {
  ASSERT_TRUE(seen_.wait(30s, [&] { return !seen_.status.empty(); })) << logs();
  line_.spy().clear();
  constexpr int kServedKills = 24;
  std::vector<double> back_s;  // from each kill to the next DDS process
  pid_t child = 0;
  Clock::time_point killed_at{};
  for (int kill = 0; kill <= kServedKills; ++kill) {
    std::vector<pid_t> children;
    ASSERT_TRUE(eventually(60s,
                           [&] {
                             children = children_of(line_.bridge().pid());
                             return children.size() == 1 && children[0] != child;
                           }))
        << "no new DDS process after kill " << kill << "\n"
        << logs();
    if (kill > 0) back_s.push_back(std::chrono::duration<double>(Clock::now() - killed_at).count());
    child = children[0];
    if (kill == kServedKills) break;
    ASSERT_TRUE(eventually(60s,
                           [&] {
                             return line_.bridge().log().find("DDS side connected (pid " + std::to_string(child) +
                                                              ",") != std::string::npos;
                           }))
        << "DDS process " << child << " never served\n"
        << logs();
    ASSERT_EQ(::kill(child, SIGKILL), 0);
    killed_at = Clock::now();
  }
  // Never given up: the last one serves.
  const auto last_kill = killed_at;
  ASSERT_TRUE(seen_.wait(60s, [&] { return !seen_.status.empty() && seen_.status.back().at > last_kill; })) << logs();

  std::ostringstream pauses;
  for (const auto b : back_s) pauses << std::fixed << std::setprecision(2) << b << " ";
  std::cout << "back after each kill (s): " << pauses.str() << "\n";
  RecordProperty("back_s", pauses.str());
  ASSERT_EQ(back_s.size(), static_cast<std::size_t>(kServedKills));
  // The figures of the back-off (docs/bus-isolation.md), not the supervisor's own table: the
  // first start and 20 restarts within a minute at once, then 1 s, 2 s, 4 s, 8 s. Under the
  // sanitizers every start is slower and the minute holds fewer: there only "never given up"
  // and the cap hold.
  for (std::size_t i = 0; i < back_s.size(); ++i) {
    EXPECT_LT(back_s[i], 30.0 + 10.0) << "kill " << i + 1 << ": " << pauses.str();
  }
  if (!kSanitized) {
    for (std::size_t i = 0; i < 20; ++i) EXPECT_LT(back_s[i], 0.9) << "restart " << i + 1 << ": " << pauses.str();
    const double expected[] = {1.0, 2.0, 4.0, 8.0};
    for (std::size_t i = 0; i < 4; ++i) {
      EXPECT_GE(back_s[20 + i], expected[i] - 0.05) << "restart " << 21 + i << ": " << pauses.str();
      EXPECT_LT(back_s[20 + i], expected[i] + 1.5) << "restart " << 21 + i << ": " << pauses.str();
    }
  }
  const auto sync = line_.spy().frames(0x80);
  ASSERT_GT(sync.size(), 100u);
  EXPECT_LT(widest_gap_ns(sync), kWidestSyncGapNs) << "SYNC gapped while the DDS processes were killed";
  EXPECT_TRUE(line_.bridge().running()) << logs();
}

// Issue 41, "the channel trusts more than the DDS side": the two processes as the package's units
// run them, as users of their own (the bus process 61001, the DDS process 61002 with the bus's
// group 61001 as a supplementary group, as SupplementaryGroups=linebridge gives it), the bus
// process taking only 61002 on the channel (--dds-user). The attacker is channel_peer, a process
// that speaks the channel. Needs root outside a user namespace (other users): skipped elsewhere.
class ChannelAttacks : public BusIsolation {
 protected:
  static constexpr uid_t kBusUser = 61001;
  static constexpr uid_t kDdsUser = 61002;
  static constexpr uid_t kAttacker = 61003;

  void SetUp() override {
    if (!other_users()) GTEST_SKIP() << "needs root outside a user namespace: the test runs processes as other users";
    dir_ = ::testing::TempDir() + "/lb_iso_channel_" + std::to_string(::getpid());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    ASSERT_EQ(::chown(dir_.c_str(), kBusUser, kBusUser), 0);
    ASSERT_EQ(::chmod(dir_.c_str(), 0750), 0);  // as /run/linebridge: the bus user's, its group may enter
    channel_ = dir_ + "/channel.sock";
    BusIsolation::SetUp();
    if (HasFatalFailure()) return;
    dds_side_ = start_dds_side("dds1");
    ASSERT_TRUE(seen_.wait(30s, [&] { return !seen_.status.empty(); })) << logs();
  }
  void TearDown() override {
    if (IsSkipped()) return;
    if (dds_side_) dds_side_->stop();
    BusIsolation::TearDown();
    std::filesystem::remove_all(dir_);
  }
  std::vector<std::string> bridge_launcher() override {
    // As the bus unit: its user, and the line's realtime_priority in effect (the unit's
    // LimitRTPRIO=49; here CAP_SYS_NICE alone, where raising the limit needs a capability a
    // container's root may lack).
    return {"/usr/bin/setpriv",
            "--reuid=" + std::to_string(kBusUser),
            "--regid=" + std::to_string(kBusUser),
            "--clear-groups",
            "--inh-caps=+sys_nice",
            "--ambient-caps=+sys_nice",
            "/bin/sh",
            "-c",
            "exec \"$0\" \"$@\" --part bus --channel " + channel_ + " --dds-user " + std::to_string(kDdsUser) +
                " --dds-absent-alarm 1"};
  }

  static bool other_users() {
    if (::geteuid() != 0) return false;
    return lb::test::run_command({"/usr/bin/setpriv", "--reuid=61099", "--regid=61099", "--clear-groups", "/bin/true"})
               .exit_code == 0;
  }
  std::unique_ptr<lb::test::ChildProcess> start_dds_side(const std::string& name) {
    return std::make_unique<lb::test::ChildProcess>(
        std::vector<std::string>{"/usr/bin/setpriv", "--reuid=" + std::to_string(kDdsUser),
                                 "--regid=" + std::to_string(kDdsUser), "--groups=" + std::to_string(kBusUser),
                                 LB_BIN_BRIDGE, "--part", "dds", "--channel", channel_, "--config",
                                 line_.bridge_config()},
        ::testing::TempDir() + "/iso_" + name + "_" + std::to_string(::getpid()) + ".log");
  }
  // channel_peer as uid:gid (groups: supplementary, "" none); its output and exit code.
  lb::test::CommandResult peer(uid_t uid, gid_t gid, const std::string& groups, std::vector<std::string> args) {
    std::vector<std::string> argv{"/usr/bin/setpriv", "--reuid=" + std::to_string(uid),
                                  "--regid=" + std::to_string(gid)};
    argv.push_back(groups.empty() ? "--clear-groups" : "--groups=" + groups);
    argv.push_back(LB_BIN_CHANNEL_PEER);
    argv.insert(argv.end(), args.begin(), args.end());
    return lb::test::run_command(std::move(argv));
  }
  std::string logs() const {
    return BusIsolation::logs() + "--- DDS side log ---\n" + (dds_side_ ? dds_side_->log() : "");
  }
  // The RPDO1 with a set value as CiA 420-4 maps it (by hand: sync speed in 0.01 %, length in 0.1 mm).
  std::size_t rpdos_with(std::uint16_t percent_hundredths, std::uint16_t length_tenth_mm) {
    std::size_t n = 0;
    for (const auto& f : line_.spy().frames(0x200 + kNode)) {
      n += f.data[2] == (percent_hundredths & 0xFF) && f.data[3] == (percent_hundredths >> 8) &&
                   f.data[4] == (length_tenth_mm & 0xFF) && f.data[5] == (length_tenth_mm >> 8)
               ? 1
               : 0;
    }
    return n;
  }
  // The DDS side's diagnostics, once they say `pred`.
  template <class Pred>
  bool diagnostics(Pred pred) {
    return seen_.wait(20s, [&] { return pred(seen_.diagnostics.dds_side()); });
  }

  std::string dir_;
  std::string channel_;
  std::unique_ptr<lb::test::ChildProcess> dds_side_;
};

// A process of another user whose primary group is the service's reaches the socket file (mode
// 0660): it was accepted, replaced the live DDS side and set saw1's values. And root's process.
TEST_F(ChannelAttacks, AnotherUserOfTheServicesGroupAndRootAreRefused) {
  std::uint32_t request = 1;
  ASSERT_NO_FATAL_FAILURE(put_set_value_in_force(request));
  const auto member = peer(kAttacker, kBusUser, "", {channel_, "setpoint", "saw1", "12.34", "0.777", "9001"});
  EXPECT_EQ(member.exit_code, 3) << member.output;
  EXPECT_NE(member.output.find("refused"), std::string::npos) << member.output;
  const auto root = lb::test::run_command(
      {LB_BIN_CHANNEL_PEER, channel_, "setpoint", "saw1", "12.34", "0.777", "9002"});
  EXPECT_EQ(root.exit_code, 3) << root.output;
  const auto stranger = peer(61004, 61004, "", {channel_, "probe"});
  EXPECT_EQ(stranger.exit_code, 3) << "the socket's mode let a user of no group of the service in: " << stranger.output;
  std::this_thread::sleep_for(300ms);  // what an accepted one would have sent is on the bus by now
  EXPECT_EQ(rpdos_with(1234, 7770), 0u) << "the attacker's set value reached saw1";
  EXPECT_TRUE(dds_side_->running()) << "the DDS side was replaced\n" << logs();
  EXPECT_NE(line_.bridge().log().find("is not the DDS side's user (uid 61002)"), std::string::npos) << logs();
  EXPECT_TRUE(diagnostics([](const auto& side) { return side.peers_refused() >= 2 && side.connects() == 1; }))
      << "peers_refused " << seen_.diagnostics.dds_side().peers_refused() << " connects "
      << seen_.diagnostics.dds_side().connects();
  // And the DDS side still serves: a set value from DDS is taken.
  write(++request, 51.0, 0.5);
  const auto answer = setpoints_.answer(request, 10s);
  EXPECT_TRUE(answer && answer->accepted()) << logs();
}

// A second process of the DDS side's own user while the DDS side is connected: it replaced it.
TEST_F(ChannelAttacks, ASecondPeerWhileTheDdsSideIsLiveIsRefused) {
  std::uint32_t request = 1;
  ASSERT_NO_FATAL_FAILURE(put_set_value_in_force(request));
  for (int i = 0; i < 5; ++i) {
    const auto second = peer(kDdsUser, kDdsUser, std::to_string(kBusUser),
                             {channel_, "setpoint", "saw1", "12.34", "0.777", "9003"});
    EXPECT_EQ(second.exit_code, 3) << second.output;
  }
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(rpdos_with(1234, 7770), 0u) << "the second peer's set value reached saw1";
  EXPECT_TRUE(dds_side_->running()) << "the live DDS side was replaced\n" << logs();
  EXPECT_NE(line_.bridge().log().find("one at a time"), std::string::npos) << logs();
  EXPECT_TRUE(diagnostics([](const auto& side) { return side.peers_refused() >= 5 && side.connects() == 1; }))
      << "peers_refused " << seen_.diagnostics.dds_side().peers_refused() << " connects "
      << seen_.diagnostics.dds_side().connects();
  write(++request, 52.0, 0.5);
  const auto answer = setpoints_.answer(request, 10s);
  EXPECT_TRUE(answer && answer->accepted()) << logs();
}

// A peer of the DDS side's user taken while no DDS side was there, which closes the channel and
// keeps its lane's descriptor: its set values stamped with the next DDS side's connection number
// (predictable) were taken while that DDS side was connected. Its lane is dead now.
TEST_F(ChannelAttacks, ALaneKeptAfterItsConnectionEndedCarriesNothing) {
  std::uint32_t request = 1;
  ASSERT_NO_FATAL_FAILURE(put_set_value_in_force(request));
  dds_side_->stop();
  ASSERT_TRUE(eventually(20s, [&] { return count_of(line_.bridge().log(), "DDS side gone") >= 1; })) << logs();
  lb::test::CommandResult stale;
  std::thread attacker([&] {
    stale = peer(kDdsUser, kDdsUser, std::to_string(kBusUser),
                 {channel_, "stale", "saw1", "23.45", "0.888", "9004", "15000"});
  });
  // The attacker connected and left; the real DDS side comes back while it sends.
  const bool attacker_in = eventually(20s, [&] { return count_of(line_.bridge().log(), "DDS side connected") >= 2; });
  dds_side_ = start_dds_side("dds2");
  attacker.join();
  ASSERT_TRUE(attacker_in) << stale.output << logs();
  EXPECT_NE(stale.output.find("closed the channel, kept 1 lane"), std::string::npos) << stale.output;
  // Dead from the moment the bus side saw the connection end (a datagram sent before that, if any,
  // found no DDS side connected and was dropped).
  EXPECT_NE(stale.output.find(" ok_after_failure=0 first error: "), std::string::npos)
      << "the lane of the ended connection took datagrams: " << stale.output;
  EXPECT_EQ(count_of(line_.bridge().log(), "DDS side connected"), 3u) << logs();
  EXPECT_EQ(rpdos_with(2345, 8880), 0u) << "the stale lane's set value reached saw1";
  // The new DDS side's own set values are taken, on its own lane.
  ASSERT_TRUE(setpoints_.wait_matched(30s)) << logs();
  bool accepted = false;
  const auto deadline = Clock::now() + 30s;
  while (!accepted && Clock::now() < deadline) {
    write(++request, 53.0, 0.5);
    const auto answer = setpoints_.answer(request, 2s);
    accepted = answer && answer->accepted();
  }
  EXPECT_TRUE(accepted) << logs();
  EXPECT_EQ(rpdos_with(2345, 8880), 0u);
}

// Both units ran as one user: a compromised DDS process could stop or kill the bus process
// (@system-service allows kill). As users of their own, the kernel refuses it. And the units
// the package ships are set up so (checked on their files: each its user, the bus process told
// the DDS unit's, the DDS unit with no capability, CAP_KILL among them).
TEST_F(ChannelAttacks, TheDdsSidesUserCannotSignalTheBusProcess) {
  line_.spy().clear();
  const auto bus_pid = std::to_string(line_.bridge().pid());
  for (const char* sig : {"STOP", "KILL", "TERM"}) {
    const auto r = peer(kDdsUser, kDdsUser, std::to_string(kBusUser), {"-", "signal", bus_pid, sig});
    EXPECT_EQ(r.exit_code, 3) << r.output;
    EXPECT_NE(r.output.find("Operation not permitted"), std::string::npos) << r.output;
  }
  std::this_thread::sleep_for(1s);
  EXPECT_TRUE(line_.bridge().running()) << logs();
  const auto sync = line_.spy().frames(0x80);
  ASSERT_GT(sync.size(), 20u) << "SYNC stopped";
  EXPECT_LT(widest_gap_ns(sync), kWidestSyncGapNs);

  const auto unit = [](const std::string& name) {
    return read_file(std::string(LB_SOURCE_DIR) + "/launch_scripts/" + name);
  };
  const auto setting = [](const std::string& text, const std::string& key) {
    const auto at = text.find("\n" + key + "=");
    if (at == std::string::npos) return std::string("(none)");
    const auto from = at + key.size() + 2;
    return text.substr(from, text.find('\n', from) - from);
  };
  const auto bus = unit("linebridge-bus.service");
  const auto dds = unit("linebridge-dds.service");
  EXPECT_EQ(setting(bus, "User"), "linebridge");
  EXPECT_EQ(setting(dds, "User"), "linebridge-dds");
  EXPECT_NE(setting(bus, "ExecStart").find("--dds-user " + setting(dds, "User") + " "), std::string::npos)
      << setting(bus, "ExecStart");
  EXPECT_EQ(setting(dds, "CapabilityBoundingSet"), "");
  EXPECT_EQ(setting(dds, "AmbientCapabilities"), "");
  EXPECT_EQ(setting(dds, "NoNewPrivileges"), "yes");
}

// The options of issue 41 belong to one part each; given to another, or naming no user, they are
// refused before anything starts (exit 2, the reason said).
TEST(BusIsolationOptions, EachPartsOwnOptionsAreRefusedElsewhere) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  const auto channel = ::testing::TempDir() + "/lb_iso_options.sock";
  const struct {
    std::vector<std::string> args;
    std::string says;
  } cases[] = {
      {{"--part", "both", "--dds-user", "root"}, "--dds-user is for --part bus"},
      {{"--part", "bus", "--channel", channel, "--dds-user", "lb-no-such-user"}, "no such user"},
      {{"--part", "bus", "--channel", channel, "--dds-user", "99999999999"}, "no such user"},
      {{"--part", "dds", "--channel", channel, "--dds-absent-alarm", "5"},
       "--dds-absent-alarm is for --part bus or both"},
      {{"--part", "bus", "--channel", channel, "--pace-starts", "/tmp/x"}, "--pace-starts is for --part dds"},
      {{"--part", "bus", "--channel", channel, "--dds-absent-alarm", "-1"}, "--dds-absent-alarm"},
  };
  for (const auto& c : cases) {
    std::vector<std::string> argv{LB_BIN_BRIDGE};
    argv.insert(argv.end(), c.args.begin(), c.args.end());
    const auto r = lb::test::run_command(argv, 20s);
    EXPECT_EQ(r.exit_code, 2) << c.args.back() << "\n" << r.output;
    EXPECT_NE(r.output.find(c.says), std::string::npos) << r.output;
  }
}
