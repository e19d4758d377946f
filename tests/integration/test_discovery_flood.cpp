// Issue 25 'Why' 1: forged discovery announcements (a real secured participant's SPDP
// announcement replayed with random GUID prefixes, no certificate behind any of them) sent to a
// secured line's discovery multicast by the real bench-forged-announcements. Fast DDS 2.9.1 starts
// a handshake with each; unbounded, 3,000 of them filled its 100-entry handshake history and the
// next real handshake aborted the bridge (SecurityManager.cpp:1498, exit 134) and SYNC with it.
// The bridge is two processes: its DDS process, past dds.max_remote_participants (default 32),
// ends and its bus process starts a fresh one (which forgets the forged participants). This test
// watches the bus with the spy through both floods: the bus process lives and SYNC keeps its
// period throughout, and a legitimate client that authenticates after the flood is answered
// within a bound.
// Runs inside launch_scripts/netns-run.sh (CTest does that): the flood never leaves the namespace.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include "can/controller_state.hpp"
#include "dds/participant.hpp"
#include "dds/service.hpp"
#include "dds/topic_names.hpp"
#include "gateways/routing/bridge_runs.hpp"
#include "msgs/commonPubSubTypes.h"
#include "support/eventually.hpp"
#include "support/line_harness.hpp"
#include "support/test_pki.hpp"

namespace srv = linebridge_msgs::srv;
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
// A legitimate client's first answer after the flood stops: the DDS process notices the flood
// within a second and a fresh one is up in well under one; the client then authenticates (~1.1 s
// with Fast DDS's handshake resend) and is answered.
constexpr auto kAnswerBound = 20s;
const std::string kDevices =
    "  - {name: saw1, bus: b, node_id: 5, profile: cia420-4, version: '3.1', heartbeat_timeout_ms: 400,\n"
    "     simulation: {heartbeat_period_ms: 100}}\n";

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
    line_.set_participant_options(pki_->options(kDomain, observer_, "flood-observer"));
    ASSERT_NO_THROW(
        line_.start(kDevices, "", ", sync_period_ms: " + std::to_string(kSyncPeriodMs) + ", realtime_priority: 20"));
    ASSERT_TRUE(line_.dds().secured());
    ASSERT_TRUE(line_.bridge().wait_log("DDS security in force", 20s)) << line_.logs();
    ASSERT_TRUE(eventually(20s, [&] { return line_.spy().frames(kSync).size() >= 10; })) << "no SYNC\n" << line_.logs();
  }

  // bench-forged-announcements: n announcements at 2,000/s to the domain's discovery multicast
  // (every participant of the domain hears it); returns once all were sent.
  void flood(int n) {
    const std::string log = dir_ + "/flood_" + std::to_string(n) + ".log";
    lb::test::ChildProcess tool({LB_BIN_FORGED, "--domain", std::to_string(kDomain), "--pki", pki_->dir(), "--identity",
                                 "replayed", "--count", std::to_string(n), "--rate", "2000", "--seed", "25"},
                                log);
    ASSERT_TRUE(tool.started());
    ASSERT_TRUE(eventually(30s, [&] { return !tool.running(); })) << "the flood tool did not finish\n" << tool.log();
    const int status = tool.stop();
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << tool.log();
    ASSERT_NE(tool.log().find("datagrams_sent=" + std::to_string(n)), std::string::npos) << tool.log();
  }

  // A new secured engineer participant (it authenticates now, after the flood) reads 1000h from
  // saw1 through the bridge; returns how long the first answer took, or nothing within the bound.
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
    srv::SdoRead_Request req;
    req.device("saw1");
    req.index(0x1000);
    req.sub_index(0);
    req.data_type("UNSIGNED32");
    while (Clock::now() - start < kAnswerBound) {
      auto r = (*client)->call(req, 5s);
      if (r && r->success()) {
        EXPECT_GE((*dds)->remote_counts().known, 1) << "answered, yet the client counts no remote participant";
        return Clock::now() - start;
      }
    }
    return std::nullopt;
  }

  std::string dir_;
  std::unique_ptr<lb::test::TestPki> pki_;
  std::string observer_, engineer_;
  lb::test::LineHarness line_{"flood", kDomain};
};

TEST_F(DiscoveryFlood, TheBusKeepsItsSyncAndARealClientIsAnsweredAfter200And3000) {
  const auto watch_from = lb::ddsl::now_ns();
  const auto bus_pid = line_.bridge().pid();
  std::size_t restarts_before = 0;
  for (const int n : {200, 3000}) {
    SCOPED_TRACE("flood of " + std::to_string(n));
    ASSERT_NO_FATAL_FAILURE(flood(n));
    const auto answered = legitimate_read();
    // The bus process is still the one the test started: only its DDS process may go.
    ASSERT_TRUE(line_.bridge().running()) << "the bus process died during or after the flood of " << n << "\n"
                                          << line_.logs();
    ASSERT_EQ(line_.bridge().pid(), bus_pid);
    // The DDS process counts its remote participants once a second (dds_side.cpp), so it may end
    // after the client was answered: wait for its restart, bounded, rather than look once (seen:
    // 1 run in 8 beside stress-ng --cpu 2 looked before it, "0 vs 0").
    std::size_t restarts = 0;
    eventually(20s, [&] { return (restarts = line_.bridge_log_count("a new DDS process starts")) > restarts_before; });
    std::printf("flood=%d answered=%s after_ms=%lld dds_restarts=%zu\n", n, answered ? "yes" : "no",
                answered
                    ? static_cast<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(*answered).count())
                    : -1LL,
                restarts - restarts_before);
    // The flood reached the DDS side (it is not vacuous): it ended at least once because of it.
    EXPECT_GT(restarts, restarts_before) << "the DDS process never noticed the flood of " << n << "\n" << line_.logs();
    restarts_before = restarts;
    EXPECT_TRUE(answered.has_value()) << "no answer within " << kAnswerBound.count() << " s after the flood of " << n
                                      << "\n"
                                      << line_.logs();
  }
  const auto gap = widest_sync_gap(line_.spy(), watch_from);
  const auto watched_ms = (lb::ddsl::now_ns() - watch_from) / 1'000'000;
  const auto dropped_for_spy = overflow_notices(line_.spy());
  const auto widest = std::chrono::milliseconds(gap.widest_ns / 1'000'000);
  std::printf("widest_sync_gap_ms=%lld syncs=%zu watched_ms=%lld overflow_notices=%llu\n",
              static_cast<long long>(widest.count()), gap.syncs, static_cast<long long>(watched_ms),
              static_cast<unsigned long long>(dropped_for_spy));
  // On a miss, say when (to set beside the logs' DDS restarts) and whether the harness itself lost
  // frames: a miss with overflow notices may be the test process's, not the bridge's.
  EXPECT_LT(widest, kMaxSyncGap) << "a SYNC was missed during the floods: the widest gap ended "
                                 << (gap.end_ns - watch_from) / 1'000'000
                                 << " ms into the watch; overflow notices at the spy: " << dropped_for_spy << "\n"
                                 << line_.logs();
  // Every period of the watch had its SYNC (a stop would show here as missing ones).
  EXPECT_GE(gap.syncs, static_cast<std::size_t>(watched_ms / kSyncPeriodMs * 9 / 10));
}

}  // namespace
