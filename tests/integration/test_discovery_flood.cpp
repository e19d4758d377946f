// Issue 25 'Why' 1 and issue 41 points 1-2: forged discovery announcements (a real secured
// participant's SPDP announcement replayed with random GUID prefixes, no certificate behind any of
// them) sent to a secured line's discovery multicast by the real bench-forged-announcements, and a
// crowd of honest participants (bench-plant-participants). Fast DDS 2.9.1 alone keeps whatever an
// announcement asks for as long as it says: unbounded, 3,000 forged ones filled its 100-entry
// handshake history and aborted the bridge (SecurityManager.cpp, exit 134); bounded by Fast DDS's
// participant limit, forged ones kept the slots and locked real clients out; the DDS process that
// ended itself past 32 remote participants restarted under any 33 honest ones. Now every
// participant of the product (the bridge's DDS process, every client) has a discovery gate in
// front of its sockets (dds/discovery_gate.hpp): an honest crowd of 40 restarts nothing and is
// served, floods restart nothing, clients running before a flood are served through it and after
// it without a restart, and SYNC keeps its period throughout. The long form (100 participants, 60 s,
// four flood rates): launch_scripts/plant-scale.sh.
// Runs inside launch_scripts/netns-run.sh (CTest does that): the flood never leaves the namespace.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <regex>
#include <string>
#include <thread>

#include "can/controller_state.hpp"
#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/routing/bridge_runs.hpp"
#include "msgs/commonPubSubTypes.h"
#include "msgs/sawPubSubTypes.h"
#include "support/eventually.hpp"
#include "support/line_harness.hpp"
#include "support/test_pki.hpp"
#include "support/thread_stacks.hpp"

namespace srv = linebridge_msgs::srv;
namespace msg = linebridge_msgs::msg;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

constexpr std::uint32_t kDomain = 45;
constexpr std::uint32_t kSync = 0x080;
constexpr int kSyncPeriodMs = 20;
// No SYNC missed: the bus loop runs at realtime priority (as the packaged unit allows), so the
// flood's load on the DDS process, the flood tool and Fast DDS's threads cannot delay it; a gap of
// two periods would be a missing SYNC.
constexpr auto kMaxSyncGap = std::chrono::milliseconds(2 * kSyncPeriodMs);
// A new client's first answer after a flood: the DDS process runs on, the client authenticates
// (~1.1 s with Fast DDS's handshake resend; its first announcements get it through the gate) and
// is answered. Generous for 2 loaded cores.
constexpr auto kAnswerBound = 10s;
// Issue 41 point 2: a client running before a flood has its status again within 5 s of the
// flood's end; here it must not lose it at all: no gap in its status samples longer than this
// (the saw's status comes every SYNC-driven TPDO, many a second; 2 loaded cores).
constexpr auto kWidestStatusGap = 2s;
const std::string kDevices =
    "  - {name: saw1, bus: b, node_id: 5, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 400,\n"
    "     simulation: {heartbeat_period_ms: 100}}\n";
// How the DDS process's gate says what it dropped (app/dds_side.cpp, at most every 10 s).
const std::string kFirstSightingsNews = "of participants not seen before dropped";
const std::string kRestart = "a new DDS process starts";

using ReadClient = lb::ddsl::ServiceClient<srv::SdoRead_RequestPubSubType, srv::SdoRead_ResponsePubSubType>;

using lb::test::eventually;

// The widest gap between consecutive SYNCs the spy saw stamped at or after `from_ns`, where it
// ended, and how many SYNCs it saw.
struct SyncGap {
  std::int64_t widest_ns = 0;
  std::int64_t end_ns = 0;
  std::size_t syncs = 0;
};
SyncGap widest_sync_gap(lb::test::BusSpy& spy, std::int64_t from_ns) {
  SyncGap out;
  std::int64_t previous = 0;
  for (const auto& f : spy.frames(kSync)) {
    if (f.timestamp_ns < from_ns) continue;
    if (previous != 0 && f.timestamp_ns - previous > out.widest_ns) {
      out.widest_ns = f.timestamp_ns - previous;
      out.end_ns = f.timestamp_ns;
    }
    previous = f.timestamp_ns;
    ++out.syncs;
  }
  return out;
}

// Overflow reports among the spy's frames: the hub dropped frames for the spy (a starved test
// process), which would show as a missing SYNC the bridge did send. Read as the bridge reads a
// controller's error frames.
std::uint64_t overflow_notices(lb::test::BusSpy& spy) {
  lb::can::BusStats stats;
  for (const auto& f : spy.frames()) lb::can::apply_error_frame(f, stats);
  return stats.rx_overflows;
}

// When each status sample of a reader arrived (the reader's callback may outlive the test's
// locals: the state is shared with it).
struct Arrivals {
  std::mutex m;
  std::vector<Clock::time_point> at;
  std::size_t between(Clock::time_point a, Clock::time_point b) {
    std::lock_guard lock(m);
    return static_cast<std::size_t>(std::count_if(at.begin(), at.end(), [&](auto t) { return t >= a && t < b; }));
  }
  // The widest gap between consecutive arrivals in [a, b], the window's ends counting as arrivals.
  Clock::duration widest_gap(Clock::time_point a, Clock::time_point b) {
    std::lock_guard lock(m);
    Clock::duration widest{};
    auto previous = a;
    for (auto t : at) {
      if (t < a || t > b) continue;
      widest = std::max(widest, t - previous);
      previous = t;
    }
    return std::max(widest, b - previous);
  }
};

class DiscoveryFlood : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(std::getenv("LINEBRIDGE_NETNS") != nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
    dir_ = std::filesystem::path(::testing::TempDir() + "/flood_" + std::to_string(::getpid()))
               .lexically_normal()
               .string();
    std::filesystem::create_directories(dir_);
    // pki.sh reads the line (its name, its devices) from an unsecured file of the same line.
    const std::string plain = dir_ + "/plain.yaml";
    std::ofstream(plain) << "line: flood\ndds: {domain: " << kDomain << "}\ndevices:\n"
                         << kDevices << "buses:\n  - {name: b, interface: 'virtual:x'}\n";
    pki_ = std::make_unique<lb::test::TestPki>(plain, dir_ + "/pki");
    observer_ = pki_->issue("observer", "observer");
    engineer_ = pki_->issue("engineer", "engineer");
    pki_->issue("replayed", "observer");  // the participant whose announcement the flood replays
    line_.set_dds_keys("  localhost_only: true\n" + pki_->security_yaml());
    // The test's own participant (the client running before the floods) forgets a forged
    // participant whose handshake it started after 15 s instead of 60: whether they are forgotten
    // is checked, not CI's patience.
    auto own = pki_->options(kDomain, observer_, "flood-observer");
    own.gate.talk_within = 15s;
    line_.set_participant_options(own);
    ASSERT_NO_THROW(
        line_.start(kDevices, "", ", sync_period_ms: " + std::to_string(kSyncPeriodMs) + ", realtime_priority: 20"));
    ASSERT_TRUE(line_.dds().secured());
    ASSERT_TRUE(line_.bridge().wait_log("DDS security in force", 20s)) << line_.logs();
    ASSERT_TRUE(eventually(20s, [&] { return line_.spy().frames(kSync).size() >= 10; })) << "no SYNC\n" << line_.logs();
  }

  // bench-forged-announcements: n announcements at `rate` to the domain's discovery multicast
  // (other forged participants for every n and rate: each flood its own seed)
  // (every participant of the domain hears it), each forged participant announcing a lease of 300 s
  // (issue 41's attacker) and sent `repeat` times; returns once all were sent.
  void flood(int n, int rate, int repeat) {
    const std::string log = dir_ + "/flood_" + std::to_string(n) + "_" + std::to_string(rate) + ".log";
    lb::test::ChildProcess tool({LB_BIN_FORGED, "--domain", std::to_string(kDomain), "--pki", pki_->dir(), "--identity",
                                 "replayed", "--count", std::to_string(n), "--rate", std::to_string(rate), "--seed",
                                 std::to_string(n * 7919 + rate), "--lease-s", "300", "--repeat",
                                 std::to_string(repeat)},
                                log);
    ASSERT_TRUE(tool.started());
    ASSERT_TRUE(eventually(60s, [&] { return !tool.running(); })) << "the flood tool did not finish\n" << tool.log();
    const int status = tool.stop();
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << tool.log();
    ASSERT_NE(tool.log().find("datagrams_sent=" + std::to_string(n * repeat)), std::string::npos) << tool.log();
  }

  // A new secured engineer participant (it authenticates now) reads 1000h from saw1 through the
  // bridge; returns how long the first answer took, or nothing within the bound.
  std::optional<Clock::duration> legitimate_read() {
    const auto start = Clock::now();
    auto dds = lb::ddsl::Participant::create(pki_->options(kDomain, engineer_, "flood-engineer"));
    if (!dds) {
      ADD_FAILURE() << dds.error().message;
      return std::nullopt;
    }
    auto client = ReadClient::create(**dds, lb::ddsl::line_service_path("flood", "sdo_read"),
                                     lb::gateways::bridge_runs("flood"));
    if (!client) {
      ADD_FAILURE() << client.error().message;
      return std::nullopt;
    }
    while (Clock::now() - start < kAnswerBound) {
      auto r = (*client)->call(read_request(), 2s);
      if (r && r->success()) {
        EXPECT_GE((*dds)->remote_counts().known, 1) << "answered, yet the client counts no remote participant";
        return Clock::now() - start;
      }
    }
    return std::nullopt;
  }

  // On a miss: whether the gate evicted them (then Fast DDS kept them) or never did.
  static std::string gate_text(const lb::ddsl::GateCounts& c) {
    return "admitted=" + std::to_string(c.admitted) + " proven=" + std::to_string(c.proven) +
           " evicted=" + std::to_string(c.evicted) + " pending_now=" + std::to_string(c.pending_now) +
           " waited=" + std::to_string(c.waited);
  }

  static srv::SdoRead_Request read_request() {
    srv::SdoRead_Request req;
    req.device("saw1");
    req.index(0x1000);
    req.sub_index(0);
    req.data_type("UNSIGNED32");
    return req;
  }

  std::string dir_;
  std::unique_ptr<lb::test::TestPki> pki_;
  std::string observer_, engineer_;
  lb::test::LineHarness line_{"flood", kDomain};
};

TEST_F(DiscoveryFlood, TheBusKeepsItsSyncAndTheDdsSideRunsOnThrough200And3000AndANewClientIsAnswered) {
  const auto watch_from = lb::ddsl::now_ns();
  const auto bus_pid = line_.bridge().pid();
  for (const int n : {200, 3000}) {
    SCOPED_TRACE("flood of " + std::to_string(n));
    const auto dropped_before = line_.bridge_log_count(kFirstSightingsNews);
    // Each sent once, as bench-forged-announcements always did: the gate's first sighting drops
    // them all (forged participants that announce twice: the next test).
    ASSERT_NO_FATAL_FAILURE(flood(n, 2000, 1));
    const auto answered = legitimate_read();
    ASSERT_TRUE(line_.bridge().running()) << "the bus process died during or after the flood of " << n << "\n"
                                          << line_.logs();
    ASSERT_EQ(line_.bridge().pid(), bus_pid);
    // The flood reached the DDS process (not vacuous): its gate says it dropped the announcements
    // (at most every 10 s).
    EXPECT_TRUE(eventually(15s, [&] { return line_.bridge_log_count(kFirstSightingsNews) > dropped_before; }))
        << "the DDS process never saw the flood of " << n << "\n"
        << line_.logs();
    std::printf("flood=%d answered=%s after_ms=%lld dds_restarts=%zu\n", n, answered ? "yes" : "no",
                answered
                    ? static_cast<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(*answered).count())
                    : -1LL,
                line_.bridge_log_count(kRestart));
    EXPECT_TRUE(answered.has_value()) << "no answer within " << kAnswerBound.count() << " s after the flood of " << n
                                      << "\n"
                                      << line_.logs();
  }
  // Nothing a flood does ends the DDS process (before: it ended itself past 32 participants).
  EXPECT_EQ(line_.bridge_log_count(kRestart), 0U) << line_.logs();
  const auto gap = widest_sync_gap(line_.spy(), watch_from);
  const auto watched_ms = (lb::ddsl::now_ns() - watch_from) / 1'000'000;
  const auto dropped_for_spy = overflow_notices(line_.spy());
  const auto widest = std::chrono::milliseconds(gap.widest_ns / 1'000'000);
  std::printf("widest_sync_gap_ms=%lld syncs=%zu watched_ms=%lld overflow_notices=%llu\n",
              static_cast<long long>(widest.count()), gap.syncs, static_cast<long long>(watched_ms),
              static_cast<unsigned long long>(dropped_for_spy));
  // On a miss, say when (to set beside the logs) and whether the harness itself lost frames: a
  // miss with overflow notices may be the test process's, not the bridge's.
  EXPECT_LT(widest, kMaxSyncGap) << "a SYNC was missed during the floods: the widest gap ended "
                                 << (gap.end_ns - watch_from) / 1'000'000
                                 << " ms into the watch; overflow notices at the spy: " << dropped_for_spy << "\n"
                                 << line_.logs();
  // Every period of the watch had its SYNC (a stop would show here as missing ones).
  EXPECT_GE(gap.syncs, static_cast<std::size_t>(watched_ms / kSyncPeriodMs * 9 / 10));
}

// Issue 41 points 1 and 2, the short form of launch_scripts/plant-scale.sh: clients of the
// product's code started first (a status reader as an HMI copies it, a ServiceClient), then 40
// honest participants (20 authenticated observers reading the saw's status, 20 applications
// without an identity on the same domain) for 10 s, then forged announcements at 40/s for 10 s
// (lease 300 s, each sent twice).
TEST_F(DiscoveryFlood, FortyHonestParticipantsAndAFloodRestartNothingAndEveryClientIsServedThroughout) {
  // The clients running before everything, never re-created.
  auto arrivals = std::make_shared<Arrivals>();
  ASSERT_TRUE(line_.dds()
                  .subscribe<msg::SawStatusPubSubType>(line_.topic("saw1", "status"), lb::ddsl::QosKind::state,
                                                       [arrivals](const msg::SawStatus&, const auto&) {
                                                         std::lock_guard lock(arrivals->m);
                                                         arrivals->at.push_back(Clock::now());
                                                       })
                  .has_value());
  auto engineer = lb::ddsl::Participant::create(pki_->options(kDomain, engineer_, "flood-hmi"));
  ASSERT_TRUE(engineer) << engineer.error().message;
  auto service = ReadClient::create(**engineer, lb::ddsl::line_service_path("flood", "sdo_read"),
                                    lb::gateways::bridge_runs("flood"));
  ASSERT_TRUE(service) << service.error().message;
  ASSERT_TRUE(eventually(20s, [&] {
    auto r = (*service)->call(read_request(), 2s);
    return r && r->success();
  })) << line_.logs();
  ASSERT_TRUE(eventually(10s, [&] { return arrivals->between(Clock::now() - 1s, Clock::now()) > 0; }));
  const auto known_before = line_.dds().remote_counts().known;

  // 1. The honest crowd: bench-plant-participants, 20 readers with observer identities of their own
  // (subjects differ: which side starts each handshake differs too) and 20 without.
  std::vector<std::string> crowd{
      LB_BIN_PLANT, "--config", line_.bridge_config(), "--participants", "20", "--bystanders", "20", "--duration", "10",
      "--every",    "5"};
  for (int i = 0; i < 4; ++i) {
    crowd.push_back("--identity");
    crowd.push_back(pki_->issue("hmi" + std::to_string(i), "observer"));
  }
  const auto crowd_from = Clock::now();
  lb::test::ChildProcess honest(crowd, dir_ + "/crowd.log");
  ASSERT_TRUE(honest.started());
  ASSERT_TRUE(eventually(90s, [&] { return !honest.running(); })) << honest.log();
  const auto crowd_to = Clock::now();
  const int crowd_status = honest.stop();
  ASSERT_TRUE(WIFEXITED(crowd_status) && WEXITSTATUS(crowd_status) == 0) << honest.log();
  std::printf("%s", honest.log().c_str());
  // Every reader had samples, and all of them in the crowd's last 5 s (a reader served once and
  // then dropped would show there).
  EXPECT_NE(honest.log().find("readers=20 readers_never_served=0"), std::string::npos) << honest.log();
  const auto text = honest.log();
  const std::regex served(R"(served=(\d+)/20)");
  std::string last_served;
  for (std::sregex_iterator it(text.begin(), text.end(), served), end; it != end; ++it) last_served = (*it)[1];
  EXPECT_EQ(last_served, "20") << honest.log();
  EXPECT_EQ(line_.bridge_log_count(kRestart), 0U) << "honest participants restarted the DDS process\n" << line_.logs();
  EXPECT_LT(arrivals->widest_gap(crowd_from, crowd_to), kWidestStatusGap)
      << "the client running before lost its status";

  // 2. The flood: 400 forged participants at 40/s, each announced twice. First the crowd's
  // participants are gone from the client (each said goodbye when its process ended).
  EXPECT_TRUE(eventually(15s, [&] { return line_.dds().remote_counts().known <= known_before; }))
      << "the crowd's participants are still known to the client: " << line_.dds().remote_counts().known
      << " (before: " << known_before << ")";
  const auto flood_from = Clock::now();
  int known_most = 0;
  std::atomic<bool> flooding{true};
  std::thread watch([&] {
    while (flooding) {
      known_most = std::max(known_most, line_.dds().remote_counts().known);
      std::this_thread::sleep_for(100ms);
    }
  });
  flood(400, 40, 2);
  const auto flood_to = Clock::now();
  flooding = false;
  watch.join();
  ASSERT_FALSE(HasFatalFailure());
  // The ServiceClient made before the flood is answered right after it (no new client).
  const auto asked = Clock::now();
  bool answered = false;
  while (!answered && Clock::now() - asked < 5s) {
    auto r = (*service)->call(read_request(), 2s);
    answered = r && r->success();
  }
  const auto after_to = Clock::now() + 5s;
  std::this_thread::sleep_until(after_to);
  std::printf(
      "status_samples crowd=%zu flood=%zu after=%zu widest_gap_ms crowd=%lld flood=%lld "
      "client_known before=%d most=%d\n",
      arrivals->between(crowd_from, crowd_to), arrivals->between(flood_from, flood_to),
      arrivals->between(flood_to, after_to),
      static_cast<long long>(
          std::chrono::duration_cast<std::chrono::milliseconds>(arrivals->widest_gap(crowd_from, crowd_to)).count()),
      static_cast<long long>(
          std::chrono::duration_cast<std::chrono::milliseconds>(arrivals->widest_gap(flood_from, after_to)).count()),
      known_before, known_most);
  std::printf("client gate after the flood: %s\n", gate_text(line_.dds().gate_counts()).c_str());
  EXPECT_TRUE(answered) << "the ServiceClient made before the flood got no answer within 5 s of its end\n"
                        << line_.logs();
  EXPECT_LT(arrivals->widest_gap(flood_from, after_to), kWidestStatusGap)
      << "the status reader made before the flood lost its samples during it or after\n"
      << line_.logs();
  EXPECT_EQ(line_.bridge_log_count(kRestart), 0U) << "the flood restarted the DDS process\n" << line_.logs();
  // The flood reached the client's participant too, and its own gate bounded what it kept: at most
  // its quotas of forged participants at once (those holding a handshake message of the client,
  // those it only waits for), all forgotten once they failed to authenticate (10 s, 15 s for those
  // it started a handshake with, plus the 250 ms a received message takes at most to come).
  const lb::ddsl::GateLimits limits;
  EXPECT_GT(known_most, known_before) << "no forged participant reached the client: the test proves nothing";
  EXPECT_LE(known_most, known_before + limits.pending + limits.waiting);
  const bool forgotten = eventually(25s, [&] { return line_.dds().remote_counts().known <= known_before; });
  // Seen once in CI (1 run in 10): 88 still known and the process hung afterwards, as if a Fast DDS
  // thread that handles discovery had stopped; the stacks say where the next time.
  EXPECT_TRUE(forgotten) << "forged participants still known to the client: " << line_.dds().remote_counts().known
                         << " (before " << known_before << "); its gate: " << gate_text(line_.dds().gate_counts())
                         << "\n"
                         << (forgotten ? std::string() : lb::test::thread_stacks());
}

}  // namespace
