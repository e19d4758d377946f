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
#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <fstream>
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
#if defined(__SANITIZE_THREAD__) || defined(__SANITIZE_ADDRESS__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(thread_sanitizer) || __has_feature(address_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif
// No SYNC missed: a gap of two periods is one missing (sanitized: no stop, 250 ms).
constexpr std::int64_t kWidestSyncGapNs = kSanitized ? 250'000'000 : 2 * kSyncPeriodNs;
// A new DDS process's first status sample at this test's subscriber after each kill (sanitized:
// 10 s). The DDS process itself is ready within 0.1 s of the kill (its log); the rest is Fast DDS
// discovery between it and this subscriber, whose resends put one kill in 20 near 1 s (measured:
// p50 90 ms, max 985 ms), so the bound is 2 s and the distribution is printed.
constexpr double kBackWithinMs = kSanitized ? 10'000.0 : 2'000.0;

// The children of a process, from every one of its threads' lists (the supervisor thread forks).
std::vector<pid_t> children_of(pid_t pid) {
  std::vector<pid_t> out;
  const std::string tasks = "/proc/" + std::to_string(pid) + "/task";
  DIR* dir = ::opendir(tasks.c_str());
  if (dir == nullptr) return out;
  while (auto* e = ::readdir(dir)) {
    if (e->d_name[0] == '.') continue;
    std::ifstream f(tasks + "/" + e->d_name + "/children");
    pid_t child = 0;
    while (f >> child) out.push_back(child);
  }
  ::closedir(dir);
  return out;
}

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
  void SetUp() override {
    ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
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
