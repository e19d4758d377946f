// What must not stall or end a bus loop, or lose a running line's set values, with the real
// bridge and simulator: a stop while clients call services, a frozen subscriber during an EMCY
// burst, a restart, another master on the bus, malformed frames and floods. Each from a finding of
// the attack run on the released bridge (issue 12); every check looks at frames (with their
// timestamps) and samples, never at the bridge's own timers.
#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <optional>
#include <random>
#include <sstream>
#include <thread>

#include "can/candump_log.hpp"
#include "msgs/sawPubSubTypes.h"
#include "support/line_harness.hpp"
#include "support/line_views.hpp"
#include "support/scratch_files.hpp"
#include "support/set_value_client.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;
using lb::ddsl::QosKind;
using Clock = std::chrono::steady_clock;
using lb::test::eventually;
using lb::test::node_of;
using lb::test::saw_entry;
constexpr auto operational = lb::test::operational<msg::SawStatus>;

namespace {

const msg::BusDiagnostics* bus_of(const msg::Diagnostics& d) { return d.buses().empty() ? nullptr : &d.buses()[0]; }

// The largest gap between consecutive SYNCs (080h) among the frames, and their number.
std::pair<std::size_t, double> syncs(const std::vector<lb::can::CanFrame>& frames) {
  std::size_t n = 0;
  std::int64_t last = 0;
  double widest_ms = 0;
  for (const auto& f : frames) {
    if (f.id != 0x080 || f.extended) continue;
    if (last != 0) widest_ms = std::max(widest_ms, static_cast<double>(f.timestamp_ns - last) / 1e6);
    last = f.timestamp_ns;
    ++n;
  }
  return {n, widest_ms};
}

lb::can::CanFrame emcy(std::uint8_t node_id, bool error) {
  return lb::can::make_frame(0x080 + node_id, {static_cast<std::uint8_t>(error ? 0x10 : 0x00),
                                               static_cast<std::uint8_t>(error ? 0x42 : 0x00),
                                               static_cast<std::uint8_t>(error ? 0x09 : 0x00), 0, 0, 0, 0, 0});
}

// The threads of a process (/proc/<pid>/task/*): name, scheduling policy (SCHED_OTHER 0,
// SCHED_FIFO 1) and realtime priority, fields 41 and 40 of each thread's stat.
struct ThreadScheduling {
  std::string name;
  int policy = -1;
  int rt_priority = -1;
};
std::vector<ThreadScheduling> thread_scheduling(pid_t pid) {
  std::vector<ThreadScheduling> out;
  std::error_code ec;
  for (const auto& task : std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/task", ec)) {
    ThreadScheduling t;
    std::getline(std::ifstream(task.path() / "comm"), t.name);
    std::string stat;
    std::getline(std::ifstream(task.path() / "stat"), stat);
    std::istringstream fields(stat.substr(stat.rfind(')') + 2));  // field 3 onwards
    std::vector<std::string> f{std::istream_iterator<std::string>(fields), {}};
    if (f.size() < 39) continue;
    t.policy = std::stoi(f[41 - 3]);
    t.rt_priority = std::stoi(f[40 - 3]);
    out.push_back(std::move(t));
  }
  return out;
}
std::optional<ThreadScheduling> thread_named(pid_t pid, const std::string& name) {
  for (auto& t : thread_scheduling(pid)) {
    if (t.name == name) return t;
  }
  return std::nullopt;
}

// Writes the set value `id` until an answer to it arrives (a client that needs an answer asks
// again), at most 10 times 2 s.
template <class Writer, class MakeSetValue>
bool answered_eventually(lb::test::Collector<msg::SetpointResultPubSubType>& results, Writer& w, MakeSetValue make,
                         std::uint64_t id) {
  for (int attempt = 0; attempt < 10; ++attempt) {
    w.write(make(id));
    if (results.wait(2s, [id](const std::vector<msg::SetpointResult>& v) {
          return std::any_of(v.begin(), v.end(),
                             [id](const msg::SetpointResult& r) { return r.request_id() == id && r.accepted(); });
        })) {
      return true;
    }
  }
  return false;
}

// The value in force of the tests below (50 %, 1.2 m), or one with a hostile speed or length.
using lb::test::saw_set_value;

// One saw's set-value side (status, answers, writer), matched both ways: what every set-value
// test starts from.
using SawClient = lb::test::SetValueClient<msg::SawStatusPubSubType, msg::SawSetpointPubSubType>;

// The frames a failure is about, as candump -l lines (stamped), for its message.
std::string frames_in_candump_format(const std::vector<lb::can::CanFrame>& frames) {
  std::string out;
  for (const auto& f : frames) out += lb::can::format_log_line(f, "spy") + "\n";
  return out;
}

}  // namespace

// SIGTERM while clients call sdo_read: the SDO clients went before the DDS callbacks stopped, and
// a request in between used a freed client (SIGSEGV in 6 of 15 stops). Every stop must be clean.
TEST(Robustness, StopWhileClientsCallServicesIsClean) {
  lb::test::LineHarness line("stopload", 21);
  line.start(saw_entry("saw1", 5));
  auto status = line.collect<msg::SawStatusPubSubType>("saw1", "status", QosKind::state);
  for (int round = 0; round < 6; ++round) {
    ASSERT_TRUE(status.wait_last(20s, operational)) << "round " << round << "\n" << line.logs();
    std::atomic<bool> stop{false};
    std::atomic<int> answered{0};
    std::vector<std::thread> callers;
    for (int c = 0; c < 3; ++c) {
      callers.emplace_back([&] {
        auto client = lb::test::LineHarness::ReadClient::create(line.dds(),
                                                                lb::ddsl::line_service_path(line.line(), "sdo_read"));
        if (!client) return;
        srv::SdoRead_Request req;
        req.device("saw1");
        req.index(0x1008);  // a segmented upload: the transfer is in flight for a while
        req.sub_index(0);
        req.data_type("VISIBLE_STRING");
        while (!stop) {
          if ((*client)->call(req, 500ms)) ++answered;
        }
      });
    }
    // The stop comes while the calls are answered: after 1, 3, 5, ... answers (a different point
    // of the transfers in each round), not after a fixed time.
    ASSERT_TRUE(eventually(60s, [&] { return answered >= 1 + 2 * round; }))
        << "round " << round << ": no call answered\n"
        << line.logs();
    const int wstatus = line.bridge().stop();
    stop = true;
    for (auto& t : callers) t.join();
    EXPECT_TRUE(WIFEXITED(wstatus)) << "round " << round << ": the bridge died of signal "
                                    << (WIFSIGNALED(wstatus) ? WTERMSIG(wstatus) : 0) << "\n"
                                    << line.logs();
    EXPECT_EQ(WIFEXITED(wstatus) ? WEXITSTATUS(wstatus) : -1, 0) << line.logs();
    EXPECT_GT(answered, 0) << "round " << round << ": no call was answered before the stop";
    const auto before = status.size();
    line.start_bridge();
    ASSERT_TRUE(status.wait(20s, [before](const std::vector<msg::SawStatus>& v) {
      for (std::size_t i = before; i < v.size(); ++i) {
        if (operational(v[i])) return true;
      }
      return false;
    })) << line.logs();
  }
}

// A subscriber of the emergency events that stops reading and acknowledging, during an EMCY burst:
// the bridge's writes must not hold up its bus loop (SYNC stopped for 7-9 s before).
TEST(Robustness, AFrozenSubscriberDuringAnEmcyBurstDoesNotStallTheBus) {
  lb::test::LineHarness line("frozen", 22);
  line.start(saw_entry("saw1", 5));
  auto status = line.operational_status<msg::SawStatusPubSubType>("saw1");
  lb::test::ChildProcess reader({LB_BIN_CLI, "--config", line.bridge_config(), "echo", "saw1", "emergency"},
                                ::testing::TempDir() + "/frozen_cli.log");
  ASSERT_TRUE(reader.started());
  // The CLI reads some (an EMCY each 200 ms until its output shows one: then it is subscribed),
  // then freezes (as a hung HMI).
  ASSERT_TRUE(eventually(60s, [&] { return line.spy().send(emcy(5, true)) && reader.wait_log("EMCY 4210h", 200ms); }))
      << "the CLI printed no EMCY\n"
      << reader.log() << line.logs();
  for (int i = 0; i < 20; ++i) ASSERT_TRUE(line.spy().send(emcy(5, i % 2 == 0)));
  ::kill(reader.pid(), SIGSTOP);
  line.spy().clear();
  // 4 s of EMCYs at 1000/s from the saw's node-ID.
  const auto start = Clock::now();
  for (int i = 0; Clock::now() - start < 4s; ++i) {
    ASSERT_TRUE(line.spy().send(emcy(5, i % 2 == 0)));
    std::this_thread::sleep_for(1ms);  // stays: paces the injected burst (1000/s)
  }
  const auto [count, widest_ms] = syncs(line.spy().frames());
  ::kill(reader.pid(), SIGCONT);
  // 4 s at 20 ms is 200 SYNCs; a loaded machine may delay some, but never by seconds.
  EXPECT_GE(count, 150u) << "SYNCs during the burst";
  EXPECT_LT(widest_ms, 1000.0) << "the bus loop stalled";
  ASSERT_TRUE(status.wait_last(5s, operational)) << line.logs();
}

// A restart must not stop a running line: the set values in force come back before the first
// RPDO, so the saw never sees its program switched off or its length at zero.
TEST(Robustness, SetValuesInForceSurviveARestart) {
  const auto dir = lb::test::fresh_dir("state");
  lb::test::LineHarness line("restart", 23);
  line.start(saw_entry("saw1", 5), "", "", "state_dir: " + dir + "\n");
  SawClient saw(line, "saw1");
  auto& status = saw.status;
  saw.writer.write(saw_set_value(1));
  ASSERT_TRUE(saw.results.wait(10s, [](const std::vector<msg::SetpointResult>& v) {
    return std::any_of(v.begin(), v.end(),
                       [](const msg::SetpointResult& r) { return r.request_id() == 1 && r.accepted(); });
  })) << line.logs();
  // Kept on disk (the store writes within 200 ms): the saw's RPDO1 with the set value in force.
  ASSERT_TRUE(eventually(30s,
                         [&dir] {
                           return lb::test::read_text(dir + "/restart.set_values")
                                      .find(" rpdo1 60200010,60050010,60020020 05008813E02E0000") != std::string::npos;
                         }))
      << "the set values were never kept in " << dir << "\n"
      << lb::test::read_text(dir + "/restart.set_values") << line.logs();

  // RPDO1 of saw 3.1: 6020h control word (program on, change of length toggled once: 0005h),
  // 6005h 5000 (50.00 %), 6002h 12000 (1.2 m in 0.1 mm).
  const std::array<std::uint8_t, 8> in_force{0x05, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00};
  ASSERT_EQ(line.bridge().stop(), 0) << line.logs();
  line.spy().clear();
  line.start_bridge();
  ASSERT_TRUE(status.wait(20s, [n = status.size()](const std::vector<msg::SawStatus>& v) {
    for (std::size_t i = n; i < v.size(); ++i) {
      if (operational(v[i]) && v[i].control_word().saw_program_on()) return true;
    }
    return false;
  })) << line.logs();
  // The first RPDO1 after the restart, then 10 SYNCs more: every RPDO1 in them is checked.
  ASSERT_FALSE(line.spy().wait_count(0x205, 1).empty()) << line.logs();
  ASSERT_TRUE(line.spy().wait_until([](const std::vector<lb::can::CanFrame>& frames) {
    return std::count_if(std::find_if(frames.begin(), frames.end(), [](const auto& f) { return f.id == 0x205; }),
                         frames.end(), [](const auto& f) { return f.id == 0x080; }) >= 10;
  })) << line.logs();
  const auto sent = line.spy().frames(0x205);
  for (const auto& f : sent) {
    ASSERT_EQ(f.len, 8);
    EXPECT_TRUE(std::equal(in_force.begin(), in_force.end(), f.data.begin()))
        << "an RPDO1 after the restart is not the set value in force";
  }
  // The simulated saw kept its program on through the restart: its status never showed it off. The
  // restarted bridge took what the running saw holds (read back), which is what it had kept too.
  EXPECT_NE(line.bridge().log().find("saw1: found operational: all set values; reading back what it holds"),
            std::string::npos)
      << line.logs();
  EXPECT_NE(line.bridge().log().find("saw1: rpdo1 read back from the device"), std::string::npos) << line.logs();
}

// Another master on a master bus (its SYNCs): the bridge yields (sends nothing there while it is
// heard), says so in its diagnostics, and takes over again once the other one is silent.
TEST(Robustness, AnotherMasterIsNoticedAndYieldedTo) {
  lb::test::LineHarness line("twomasters", 24);
  line.start(saw_entry("saw1", 5));
  auto status = line.operational_status<msg::SawStatusPubSubType>("saw1");
  auto diag = line.collect<msg::DiagnosticsPubSubType>("bridge", "diagnostics", QosKind::state);

  // The other master: a SYNC every 20 ms for 3 s (the test's frames never reach the test's spy).
  line.spy().clear();
  for (int i = 0; i < 150; ++i) {
    ASSERT_TRUE(line.spy().send(lb::can::make_frame(0x080, {})));
    std::this_thread::sleep_for(20ms);  // stays: paces the other master's SYNC (its period)
  }
  const auto during = line.spy().frames();
  ASSERT_TRUE(diag.wait_last(3s, [](const msg::Diagnostics& d) {
    const auto* b = bus_of(d);
    return b != nullptr && b->yielding_to_other_master() && b->other_master_frames() >= 50 &&
           b->other_master_last().find("SYNC") != std::string::npos;
  })) << line.logs();
  // A producer that runs is the evidence: at least 20 SYNCs over at least 2 s
  // (canopen-master.md, "What the master believes"). From then on the bridge sent nothing: count
  // its frames in the last 0.5 s.
  const auto cut = during.front().timestamp_ns + 2'500'000'000;
  std::size_t bridge_frames = 0;
  for (const auto& f : during) {
    if (f.timestamp_ns > cut && (f.id == 0x080 || f.id == 0x205 || f.id == 0x000 || f.id == 0x605)) ++bridge_frames;
  }
  EXPECT_EQ(bridge_frames, 0u) << "the bridge kept transmitting beside another master";
  EXPECT_NE(line.bridge().log().find("another master's SYNC runs on this bus"), std::string::npos);
  // Silent for 5 s: the bridge produces SYNC again (30 of its SYNCs on the bus, waited for).
  line.spy().clear();
  EXPECT_GE(line.spy().wait_count(0x080, 30, 60s).size(), 30u) << line.logs();
  ASSERT_TRUE(diag.wait_last(30s, [](const msg::Diagnostics& d) {
    const auto* b = bus_of(d);
    return b != nullptr && !b->yielding_to_other_master();
  })) << line.logs();
}

// A few spoofed frames take no control away (issue 24): 12 spoofed boot-ups of the running saw in
// 6 s, each answered by its own heartbeat saying operational, and 3 foreign SYNCs within a second.
// Before, the boot-ups made a boot-up storm (no RPDO for minutes, program off refused) and the
// SYNCs silenced the whole master for 5 s. Now: not believed, counted, SYNC goes on, and a
// program-off set value reaches the saw.
TEST(Robustness, SpoofedBootUpsAndStraySyncsTakeNoControlAway) {
  lb::test::LineHarness line("spoof", 29);
  line.start(saw_entry("saw1", 5));
  SawClient saw(line, "saw1");
  lb::test::Collector<msg::DiagnosticsPubSubType> diag;
  ASSERT_TRUE(diag.subscribe(line.dds(), line.topic("bridge", "diagnostics"), QosKind::state));
  saw.writer.write(saw_set_value(1));
  ASSERT_TRUE(saw.results.wait(10s, [](const std::vector<msg::SetpointResult>& v) {
    return std::any_of(v.begin(), v.end(),
                       [](const msg::SetpointResult& r) { return r.request_id() == 1 && r.accepted(); });
  })) << line.logs();
  line.spy().clear();
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(line.spy().send(lb::can::make_frame(0x080, {})));
  for (int i = 0; i < 12; ++i) {
    ASSERT_TRUE(line.spy().send(lb::can::make_frame(0x705, {0x00})));
    std::this_thread::sleep_for(500ms);  // stays: paces the spoofed boot-ups (12 in 6 s)
  }
  // The bridge's own SYNC never stopped (the test's frames never reach its spy).
  const auto [count, widest_ms] = syncs(line.spy().frames());
  EXPECT_GE(count, 200u) << "SYNCs in 6 s at 20 ms: the master went silent";
  EXPECT_LT(widest_ms, 1000.0) << "the master went silent";
  // Program off reaches the saw: an RPDO1 with 6020h bit 0 clear.
  auto off = saw_set_value(2);
  off.saw_program_on(false);
  saw.writer.write(off);
  ASSERT_TRUE(saw.results.wait(10s, [](const std::vector<msg::SetpointResult>& v) {
    return std::any_of(v.begin(), v.end(),
                       [](const msg::SetpointResult& r) { return r.request_id() == 2 && r.accepted(); });
  })) << line.logs();
  EXPECT_TRUE(line.spy().wait_until([](const std::vector<lb::can::CanFrame>& frames) {
    return std::any_of(frames.begin(), frames.end(),
                       [](const auto& f) { return f.id == 0x205 && f.len == 8 && (f.data[0] & 0x01) == 0; });
  })) << "no RPDO1 with the program off reached the saw\n"
      << line.logs();
  ASSERT_TRUE(diag.wait_last(5s, [](const msg::Diagnostics& d) {
    const auto* n = node_of(d, "saw1");
    const auto* b = bus_of(d);
    return n != nullptr && b != nullptr && n->boot_ups_not_believed() >= 12 && n->boot_state() == "started" &&
           !b->yielding_to_other_master() && b->other_master_frames() >= 3;
  })) << line.logs();
  EXPECT_EQ(line.bridge().log().find("boot-up storm"), std::string::npos) << line.logs();
}

// The bridge's own SDO traffic is bounded: a feeder box whose FF10h error bit chatters for 10 s
// (feeder 1 in error, cleared, in error, ...: every EMCY asks for 6007h sub 1) must not queue a
// read per EMCY in front of the services. Before, each EMCY queued one and an operator's request
// waited behind thousands; now one read per feeder at a time, the rest coalesced.
// The chatter (up to 4,000 EMCYs a second) loads the simulator, the bridge and the virtual bus
// too: under the sanitizers beside a CPU burner, a probe's answer once took over a second to
// reach the bridge (seen: two probes of twenty aborted by the 1-s SDO timeout, 2.4 s each). So
// the SDO timeout is 3 s here and the bound 5 s: a backlog still shows, since it grows by
// thousands of reads a second and a probe behind it waits for all of them.
TEST(Robustness, AChatteringFeederErrorBitDoesNotStarveServiceRequests) {
  lb::test::LineHarness line("chatter", 30);
  line.start("  - name: feeders\n    bus: b\n    node_id: 10\n    profile: cia414-2\n    version: '1.1'\n"
             "    heartbeat_timeout_ms: 400\n    simulation: {heartbeat_period_ms: 100}\n",
             "", ", sdo_timeout_ms: 3000");
  auto info = line.collect<msg::DeviceInfoPubSubType>("feeders", "info", QosKind::state);
  ASSERT_TRUE(info.wait_last(30s, [](const msg::DeviceInfo& i) { return i.started(); })) << line.logs();
  std::atomic<bool> stop{false};
  std::atomic<std::uint64_t> sent{0};
  std::thread chatter([&] {
    for (std::uint64_t i = 0; !stop; ++i) {
      const std::uint8_t bitmap = i % 2 == 0 ? 0x01 : 0x00;
      if (line.spy().send(lb::can::make_frame(0x080 + 10, {0x10, 0xFF, 0x01, bitmap, 0x00, 0x00, 0x00, 0x00}))) ++sent;
      if (i % 4 == 0) std::this_thread::sleep_for(1ms);  // stays: paces the injected chatter
    }
  });
  std::vector<double> waits_ms;
  const auto start = Clock::now();
  while (Clock::now() - start < 10s) {
    // Stays: the cadence of the probes whose waits are what this test measures.
    std::this_thread::sleep_for(500ms);
    const auto t0 = Clock::now();
    const auto r = line.sdo_read("feeders", 0x1000, 0, "UNSIGNED32");
    waits_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    EXPECT_TRUE(r.success()) << r.message();
  }
  stop = true;
  chatter.join();
  EXPECT_GT(sent.load(), 5000u) << "the chatter did not happen: the test proves nothing";
  ASSERT_FALSE(waits_ms.empty());
  std::printf("probes=%zu longest_wait_ms=%.1f chatter_frames=%llu\n", waits_ms.size(),
              *std::max_element(waits_ms.begin(), waits_ms.end()), static_cast<unsigned long long>(sent.load()));
  for (const auto w : waits_ms) EXPECT_LT(w, 5000.0) << "a service request waited behind the bridge's own reads";
  EXPECT_TRUE(line.bridge().running());
}

// Malformed EMCYs and heartbeats, frames of unknown nodes and an EMCY flood are counted in the
// diagnostics, and the flood does not flood the log.
TEST(Robustness, MalformedFramesAreCountedAndFloodsLoggedAtABoundedRate) {
  lb::test::LineHarness line("malformed", 25);
  line.start(saw_entry("saw1", 5));
  auto status = line.operational_status<msg::SawStatusPubSubType>("saw1");
  auto diag = line.collect<msg::DiagnosticsPubSubType>("bridge", "diagnostics", QosKind::state);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(line.spy().send(lb::can::make_frame(0x085, {0x10, 0x42})));  // 2-byte EMCY
  for (int i = 0; i < 2; ++i) ASSERT_TRUE(line.spy().send(lb::can::make_frame(0x705, {})));         // empty heartbeat
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(line.spy().send(lb::can::make_frame(0x1A0, {1, 2, 3})));  // TPDO1 of node 32
  const auto before = line.bridge_log_count("node 5 EMCY");
  for (int i = 0; i < 2000; ++i) {
    ASSERT_TRUE(line.spy().send(emcy(5, i % 2 == 0)));
    if (i % 10 == 0) std::this_thread::sleep_for(1ms);  // stays: paces the injected flood
  }
  ASSERT_TRUE(diag.wait_last(5s, [](const msg::Diagnostics& d) {
    const auto* n = node_of(d, "saw1");
    const auto* b = bus_of(d);
    return n != nullptr && b != nullptr && n->malformed_emergencies() == 3 && n->malformed_heartbeats() == 2 &&
           n->emergencies() >= 2000 && b->frames_unclaimed() >= 4;
  })) << line.logs();
  // The next EMCY after the flood's second has passed says how many were not logged: one more
  // each 300 ms until the log says it (a few at most; the bound below leaves room for them).
  ASSERT_TRUE(eventually(30s, [&] {
    if (!line.spy().send(emcy(5, false))) return false;
    return line.bridge().wait_log("more not logged", 300ms);
  })) << line.logs();
  // 2000 EMCYs within a second or two: a few lines a second get through, with the count of the others.
  EXPECT_LT(line.bridge_log_count("node 5 EMCY") - before, 40u) << "one log line per EMCY";
  ASSERT_TRUE(status.wait_last(5s, operational));
}

// Hostile set values (NaN, infinities, huge, negative, an unknown enumeration value), a 10 kB
// string in a service request, and a flood of 3000 set values from three writers: each hostile one
// is refused with its reason, nothing of it reaches the bus (every RPDO1 stays the set value in
// force), SYNC goes on through the flood, and the bridge answers afterwards.
TEST(Robustness, HostileRequestsAreRefusedAndNothingReachesTheBus) {
  lb::test::LineHarness line("hostile_dds", 26);
  line.start(saw_entry("saw1", 5));
  SawClient saw(line, "saw1");
  const auto valid = [](std::uint64_t id) { return saw_set_value(id); };
  saw.writer.write(valid(1));
  ASSERT_TRUE(
      saw.results.wait_last(5s, [](const msg::SetpointResult& r) { return r.request_id() == 1 && r.accepted(); }));
  // RPDO1 of saw 3.1 (6020h control word 0005h, 6005h 5000 = 50.00 %, 6002h 12000 = 1.2 m in 0.1 mm),
  // on the bus before the hostile ones come.
  const std::array<std::uint8_t, 8> in_force{0x05, 0x00, 0x88, 0x13, 0xE0, 0x2E, 0x00, 0x00};
  ASSERT_TRUE(line.spy().wait_until([&in_force](const std::vector<lb::can::CanFrame>& frames) {
    return std::any_of(frames.begin(), frames.end(), [&in_force](const auto& f) {
      return f.id == 0x205 && f.len == 8 && std::equal(in_force.begin(), in_force.end(), f.data.begin());
    });
  })) << line.logs();
  line.spy().clear();

  const double inf = std::numeric_limits<double>::infinity();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<msg::SawSetpoint> hostile;
  for (double length : {nan, inf, -inf, 1e308, -1.0}) {
    auto sp = valid(100 + hostile.size());
    sp.product_length_m(length);
    hostile.push_back(sp);
  }
  for (double speed : {nan, inf, -1e308, 1e9}) {
    auto sp = valid(100 + hostile.size());
    sp.sync_speed_percent(speed);
    hostile.push_back(sp);
  }
  auto odd_mode = valid(100 + hostile.size());
  odd_mode.count_mode(static_cast<msg::SawCountMode>(77));
  hostile.push_back(odd_mode);
  for (const auto& sp : hostile) saw.writer.write(sp);
  ASSERT_TRUE(saw.results.wait(10s,
                               [n = hostile.size()](const std::vector<msg::SetpointResult>& v) {
                                 std::size_t refused = 0;
                                 for (const auto& r : v)
                                   refused += r.request_id() >= 100 && r.request_id() < 100 + n && !r.accepted() &&
                                              !r.reason().empty();
                                 return refused == n;
                               }))
      << "every hostile set value refused with its reason\n"
      << line.logs();
  for (const auto& r : saw.results.samples()) {
    if (r.request_id() >= 100 && r.request_id() < 100 + hostile.size()) {
      EXPECT_FALSE(r.accepted()) << r.request_id();
    }
  }

  // A 10 kB device name and data type in a line-wide service request: a refusal, not silence.
  auto client = lb::test::LineHarness::ReadClient::create(line.dds(),
                                                          lb::ddsl::line_service_path(line.line(), "sdo_read"));
  ASSERT_TRUE(client);
  srv::SdoRead_Request req;
  req.device(std::string(10'000, 'x'));
  req.index(0x1008);
  req.sub_index(0);
  req.data_type(std::string(10'000, 'T'));
  const auto answer = (*client)->call(req, 10s);
  ASSERT_TRUE(answer) << answer.error().message;
  EXPECT_FALSE(answer->success());
  req.device("saw1");
  const auto answer2 = (*client)->call(req, 10s);
  ASSERT_TRUE(answer2) << answer2.error().message;
  EXPECT_FALSE(answer2->success()) << "a data type of 10 kB accepted";

  // The flood: three writers, 1000 set values each, as fast as they can (all the value in force).
  // Each writer's first set value is answered before its flood: the bridge counts what a writer
  // loses from the gaps between the samples it gets, so it cannot know of samples lost before the
  // first one of a new writer reaches it (README: "Requests written faster than read").
  auto diag = line.collect<msg::DiagnosticsPubSubType>("bridge", "diagnostics", QosKind::state);
  ASSERT_TRUE(diag.wait(5s, [](const std::vector<msg::Diagnostics>& v) { return !v.empty(); }));
  const auto lost_before = diag.samples().back().commands_lost();
  std::vector<std::thread> flooders;
  for (int w = 0; w < 3; ++w) {
    flooders.emplace_back([&line, &valid, &saw, w] {
      auto fw = line.dds().writer<msg::SawSetpointPubSubType>(line.topic("saw1", "setpoint"), QosKind::command);
      if (!fw) return;
      eventually(30s, [&fw] { return fw->matched() != 0; });  // if not, the first answer below fails
      if (!answered_eventually(saw.results, *fw, valid, 20'000 + static_cast<std::uint64_t>(w))) {
        return;  // the count below comes up short and says so
      }
      for (int i = 0; i < 1000; ++i) fw->write(valid(10'000 + w * 1000 + i));
      // A closing set value, sent until answered: the bridge's reader keeps the latest 16 of all
      // writers together, so a writer's last flood samples can be overwritten there, and only a
      // later sample of the same writer shows the gap.
      answered_eventually(saw.results, *fw, valid, 30'000 + static_cast<std::uint64_t>(w));
    });
  }
  for (auto& t : flooders) t.join();
  // Asked until answered, as linebridge-cli set does: written once, its answer (the bridge's reply
  // writer's last sample after a burst) can fail to arrive though the bridge applied it (README,
  // "Requests written faster than read").
  ASSERT_TRUE(answered_eventually(saw.results, saw.writer, valid, 99'999)) << "no answer after the flood\n"
                                                                           << line.logs();
  std::size_t flood_answered = 0;
  const auto count_answered = [&] {
    flood_answered = 0;
    for (const auto& r : saw.results.samples()) flood_answered += r.request_id() >= 10'000 && r.request_id() < 13'000;
  };
  // Every set value of the flood is accounted for: answered, counted lost on its way to the bridge
  // (commands_lost, from the diagnostics published once a second), or its answer lost on the way
  // back (a gap in the bridge's reply numbers: the answers come as fast as the set values). One
  // the bridge took and neither answered nor counted leaves the sum short.
  const auto replies_lost = saw.results.gaps();
  const bool accounted = diag.wait(30s, [&](const std::vector<msg::Diagnostics>& v) {
    count_answered();
    return flood_answered + (v.back().commands_lost() - lost_before) + replies_lost >= 3000;
  });
  const auto lost = diag.samples().back().commands_lost() - lost_before;
  std::cout << "flood: 3000 set values written, " << flood_answered << " answers seen, " << lost
            << " counted as lost by the bridge, " << replies_lost << " answers lost on the way back\n";
  EXPECT_TRUE(accounted) << "set values neither answered nor counted lost\n" << line.logs();

  const auto frames = line.spy().frames();
  const auto [count, widest_ms] = syncs(frames);
  EXPECT_GT(count, 10u);
  EXPECT_LT(widest_ms, 1000.0) << "the bus loop stalled during the flood";
  std::size_t rpdos = 0;
  for (const auto& f : frames) {
    if (f.id != 0x205 || f.extended) continue;
    ++rpdos;
    ASSERT_EQ(f.len, 8);
    EXPECT_TRUE(std::equal(in_force.begin(), in_force.end(), f.data.begin())) << "a hostile set value reached the bus";
  }
  EXPECT_GT(rpdos, 0u);
  ASSERT_TRUE(saw.status.wait_last(5s, operational));
}

// An application writing set values as fast as it can (bench.sh's soak found ~47,000 refusals a
// second, each a log line: 5.6 million lines in 2 minutes): every set value that reaches the bridge
// is still answered, but the log gets a few lines a second, with the count of the others, whether
// the set values are refused or taken.
TEST(Robustness, ASetValueFloodIsAnsweredButLoggedAtABoundedRate) {
  lb::test::LineHarness line("setvalue_flood", 33);
  line.start(saw_entry("saw1", 5));
  SawClient saw(line, "saw1");
  const auto set_value = [](std::uint64_t id, double length) { return saw_set_value(id, 50, length); };
  const auto answered = [&saw](std::uint64_t first, std::uint64_t end, bool accepted) {
    std::size_t n = 0;
    for (const auto& r : saw.results.samples())
      n += r.request_id() >= first && r.request_id() < end && r.accepted() == accepted;
    return n;
  };
  const auto refused_lines = line.bridge_log_count("refused: product_length_m");
  const auto taken_lines = line.bridge_log_count(": set values: ");
  // 2000 refused (NaN length) and 2000 taken, paced only so that most reach the bridge (the
  // writer's keep-last 16 would otherwise replace them before they are sent).
  for (std::uint64_t i = 0; i < 2000; ++i) {
    saw.writer.write(set_value(1000 + i, std::numeric_limits<double>::quiet_NaN()));
    if (i % 10 == 9) std::this_thread::sleep_for(1ms);  // stays: paces the flood
  }
  for (std::uint64_t i = 0; i < 2000; ++i) {
    saw.writer.write(set_value(5000 + i, 1.0 + static_cast<double>(i) * 0.001));
    if (i % 10 == 9) std::this_thread::sleep_for(1ms);  // stays: paces the flood
  }
  // After the flood's second has passed, one more of each says how many were not logged. Stays:
  // the bridge's log limit counts in seconds of its own, and a sleep is a lower bound on that time
  // however loaded the machine (the lines that prove it are waited for below).
  std::this_thread::sleep_for(1100ms);
  saw.writer.write(set_value(9000, std::numeric_limits<double>::quiet_NaN()));
  saw.writer.write(set_value(9001, 2.5));
  ASSERT_TRUE(saw.results.wait(10s, [](const std::vector<msg::SetpointResult>& v) {
    return std::any_of(v.begin(), v.end(), [](const msg::SetpointResult& r) { return r.request_id() == 9001; });
  })) << line.logs();
  // Both answered; the count of those held back on the set-value lines themselves (a refusal's
  // line and a taken one's), waited for in the log.
  const auto held_back_lines = [&line] {
    std::istringstream log(line.bridge().log());
    std::size_t n = 0;
    for (std::string text; std::getline(log, text);) {
      n += text.find("set value") != std::string::npos && text.find("more not logged") != std::string::npos;
    }
    return n;
  };
  EXPECT_TRUE(eventually(30s, [&] { return held_back_lines() >= 2; }))
      << "no set-value line says how many were held back\n"
      << line.logs();
  EXPECT_TRUE(saw.results.wait(30s, [](const std::vector<msg::SetpointResult>& v) {
    return std::any_of(v.begin(), v.end(), [](const msg::SetpointResult& r) { return r.request_id() == 9000; });
  }));

  const auto refused = answered(1000, 3000, false);
  const auto taken = answered(5000, 7000, true);
  std::cout << "set-value flood: " << refused << " of 2000 refused and " << taken
            << " of 2000 taken were answered; log lines "
            << line.bridge_log_count("refused: product_length_m") - refused_lines << " and "
            << line.bridge_log_count(": set values: ") - taken_lines << "\n";
  ASSERT_GT(refused, 200u) << "the flood did not reach the bridge: nothing to judge";
  ASSERT_GT(taken, 200u) << "the flood did not reach the bridge: nothing to judge";
  // Two floods of about a second each, 5 lines a second allowed for each kind, and the last ones.
  EXPECT_LT(line.bridge_log_count("refused: product_length_m") - refused_lines, 40u) << "one log line per refusal";
  EXPECT_LT(line.bridge_log_count(": set values: ") - taken_lines, 40u) << "one log line per set value taken";
  EXPECT_EQ(answered(9000, 9001, false), 1u);
  EXPECT_EQ(answered(9001, 9002, true), 1u);
  ASSERT_TRUE(saw.status.wait_last(5s, operational));
}

// Random frames at the full rate of a 500 kbit/s bus (every identifier, both formats, every length,
// remote requests), a boot-up flood from nodes nobody configured and SDO replies nobody asked for,
// against a master bus: the saw stays operational, SYNC keeps its period, and the frames are
// counted rather than acted upon.
TEST(Robustness, HostileFramesAtFullLoadDoNotDisturbTheMaster) {
  lb::test::LineHarness line("hostile_can", 27);
  line.start(saw_entry("saw1", 5));
  auto status = line.operational_status<msg::SawStatusPubSubType>("saw1");
  line.spy().clear();
  std::mt19937 rng(12);
  const auto other = [&rng] {
    const auto n = static_cast<std::uint32_t>(1 + rng() % 127);
    return n == 5 ? 6u : n;
  };
  const auto start = Clock::now();
  std::size_t sent = 0;
  // ~4000 frames/s for 3 s (a 500 kbit/s bus carries about 4000 8-byte frames a second).
  for (int i = 0; Clock::now() - start < 3s; ++i) {
    lb::can::CanFrame f;
    switch (i % 8) {
      // Boot-ups of nodes the line does not have, SDO replies nobody asked for.
      case 0: f = lb::can::make_frame(0x700 + other(), {0x00}); break;
      case 1: f = lb::can::make_frame(0x580 + other(), {0x43, 0x00, 0x10, 0x00, 1, 2, 3, 4}); break;
      default: {
        f.extended = rng() % 4 == 0;
        f.id = f.extended ? rng() % 0x20000000u : rng() % 0x800u;
        // Not the saw's own identifiers (a boot-up or heartbeat there would rightly make the bridge
        // boot it again) and not NMT or SYNC (another master: AnotherMasterIsNoticedAndYieldedTo).
        if (!f.extended && ((f.id & 0x7F) == 5 || f.id == 0x000 || f.id == 0x080)) f.id = 0x7FF;
        f.rtr = rng() % 16 == 0;
        f.len = static_cast<std::uint8_t>(rng() % 9);
        for (auto& b : f.data) b = static_cast<std::uint8_t>(rng());
      }
    }
    if (line.spy().send(f)) ++sent;
    if (i % 4 == 0) std::this_thread::sleep_for(1ms);  // stays: paces the injected load
  }
  const auto frames = line.spy().frames();
  const auto [count, widest_ms] = syncs(frames);
  EXPECT_GT(sent, 3000u) << "the flood did not happen: the test proves nothing";
  EXPECT_GE(count, 110u) << "SYNCs during 3 s of hostile frames (150 at 20 ms)";
  EXPECT_LT(widest_ms, 1000.0);
  ASSERT_TRUE(status.wait_last(5s, operational)) << line.logs();
  // Still answering, still a master, still the one saw.
  auto diag = line.collect<msg::DiagnosticsPubSubType>("bridge", "diagnostics", QosKind::state);
  ASSERT_TRUE(diag.wait_last(5s, [](const msg::Diagnostics& d) {
    const auto* n = node_of(d, "saw1");
    const auto* b = bus_of(d);
    return n != nullptr && b != nullptr && n->online() && b->frames_unclaimed() > 100;
  })) << line.logs();
  EXPECT_EQ(line.bridge().running(), true);
}

// A device that freezes (its process stopped: no heartbeat, no answers) and one that dies and
// powers up again: the bridge reports it offline, SYNC goes on meanwhile, and when it is heard
// again it is booted again (SDO traffic before any NMT start), never just started.
TEST(Robustness, AFrozenThenKilledSimulatorIsSupervisedAndBootedAgain) {
  lb::test::LineHarness line("simfault", 28);
  line.start(saw_entry("saw1", 5));
  auto status = line.operational_status<msg::SawStatusPubSubType>("saw1");
  const auto offline = [](const msg::SawStatus& s) { return !s.health().online(); };
  // The first SDO request to the saw (605h) and the first NMT start of it, from the frames.
  const auto boot_then_start = [](const std::vector<lb::can::CanFrame>& frames) {
    std::int64_t sdo = 0, start = 0;
    for (const auto& f : frames) {
      if (f.extended) continue;
      if (f.id == 0x605 && sdo == 0) sdo = f.timestamp_ns;
      if (f.id == 0x000 && f.len == 2 && f.data[0] == 0x01 && (f.data[1] == 5 || f.data[1] == 0) && start == 0)
        start = f.timestamp_ns;
    }
    return std::pair{sdo, start};
  };

  line.spy().clear();
  ::kill(line.sim().pid(), SIGSTOP);
  ASSERT_TRUE(status.wait_last(5s, offline)) << "a frozen device still shown online\n" << line.logs();
  // SYNC goes on while the device is frozen: 40 more of them on the bus, waited for.
  const auto syncs_before = line.spy().frames(0x080).size();
  EXPECT_GE(line.spy().wait_count(0x080, syncs_before + 40).size(), syncs_before + 40)
      << "SYNC stopped while the device was frozen";
  const auto frozen_gap = syncs(line.spy().frames()).second;
  EXPECT_LT(frozen_gap, 1000.0);
  ::kill(line.sim().pid(), SIGCONT);
  ASSERT_TRUE(status.wait_last(20s, operational)) << line.logs();
  {
    const auto [sdo, start] = boot_then_start(line.spy().frames());
    EXPECT_NE(sdo, 0) << "the device came back and was not booted again";
    if (start != 0) {
      // Seen once in CI under a load of 9 on 2 cores (not in 6 runs here): the frames and the logs say why.
      EXPECT_LT(sdo, start) << "NMT start before the boot's SDO\n"
                            << frames_in_candump_format(line.spy().frames()) << line.logs();
    }
  }

  line.spy().clear();
  ::kill(line.sim().pid(), SIGKILL);
  ASSERT_TRUE(status.wait_last(5s, offline)) << "a dead device still shown online\n" << line.logs();
  // NMT to a device that is gone: sent (a reset may help) and answered sent, saying that nothing
  // confirms it yet (NMT is unconfirmed).
  {
    auto nmt = lb::test::LineHarness::NmtClient::create(line.dds(), lb::ddsl::line_service_path(line.line(), "nmt"));
    ASSERT_TRUE(nmt);
    srv::Nmt_Request req;
    req.device("saw1");
    req.command(srv::NMT_RESET_NODE);
    const auto answer = (*nmt)->call(req, 10s);
    ASSERT_TRUE(answer) << answer.error().message;
    EXPECT_TRUE(answer->success()) << "NMT sent to an offline device answered as not sent: " << answer->message();
    EXPECT_NE(answer->message().find("saw1 was not heard before (no heartbeat within its timeout): its boot-up will "
                                     "tell that it took effect"),
              std::string::npos)
        << answer->message();
    EXPECT_TRUE(line.spy().wait_until([](const std::vector<lb::can::CanFrame>& frames) {
      return std::any_of(frames.begin(), frames.end(), [](const lb::can::CanFrame& f) {
        return f.id == 0x000 && f.len == 2 && f.data[0] == 0x81 && f.data[1] == 5;
      });
    })) << "the reset was not sent";
  }
  line.start_sim();
  ASSERT_TRUE(status.wait_last(20s, operational)) << line.logs();
  const auto [sdo, start] = boot_then_start(line.spy().frames());
  EXPECT_NE(sdo, 0) << "the device powered up again and was not booted";
  if (start != 0) {
    EXPECT_LT(sdo, start) << "NMT start before the boot's SDO";
  }
  EXPECT_TRUE(line.bridge().running());
}

// realtime_priority: the bus loop, and only it, runs SCHED_FIFO at the configured priority, so
// SYNC and the RPDOs go out before the bridge's DDS threads and anything else of normal priority.
TEST(Robustness, ABusLoopRunsAtItsRealtimePriority) {
  // A container without CAP_SYS_NICE refuses it to everyone; the refusal has the test below.
  bool allowed = false;
  std::thread probe([&allowed] {
    sched_param p{};
    p.sched_priority = 20;
    allowed = ::pthread_setschedparam(::pthread_self(), SCHED_FIFO, &p) == 0;
  });
  probe.join();
  if (!allowed) GTEST_SKIP() << "this machine refuses SCHED_FIFO to the tests too (no CAP_SYS_NICE, RLIMIT_RTPRIO 0)";
  lb::test::LineHarness line("realtime", 34);
  line.start(saw_entry("saw1", 5), "", ", realtime_priority: 20");
  auto status = line.operational_status<msg::SawStatusPubSubType>("saw1");
  const auto loop = thread_named(line.bridge().pid(), "lb-bus-b");
  ASSERT_TRUE(loop.has_value()) << "no thread lb-bus-b in the bridge";
  EXPECT_EQ(loop->policy, SCHED_FIFO);
  EXPECT_EQ(loop->rt_priority, 20);
  for (const auto& t : thread_scheduling(line.bridge().pid())) {
    if (t.name != "lb-bus-b") {
      EXPECT_EQ(t.policy, SCHED_OTHER) << "thread " << t.name << " is realtime too";
    }
  }
  EXPECT_TRUE(line.bridge().wait_log("the bus loop runs at realtime priority 20 (SCHED_FIFO)", 1s)) << line.logs();
}

// Where the system refuses realtime (no CAP_SYS_NICE, RLIMIT_RTPRIO 0: a unit without
// LimitRTPRIO=), the bridge says so and why, and the line runs at normal priority all the same.
TEST(Robustness, ARefusedRealtimePriorityIsLoggedAndTheLineRuns) {
  lb::test::LineHarness line("realtime_refused", 35);
  line.set_bridge_launcher(
      {"/usr/bin/prlimit", "--rtprio=0", "/usr/bin/setpriv", "--bounding-set=-sys_nice", "--inh-caps=-sys_nice", "--"});
  line.start(saw_entry("saw1", 5), "", ", realtime_priority: 20");
  auto status = line.operational_status<msg::SawStatusPubSubType>("saw1");
  EXPECT_TRUE(line.bridge().wait_log("realtime priority 20 (SCHED_FIFO) refused: Operation not permitted", 1s))
      << line.logs();
  const auto loop = thread_named(line.bridge().pid(), "lb-bus-b");
  ASSERT_TRUE(loop.has_value()) << "no thread lb-bus-b in the bridge";
  EXPECT_EQ(loop->policy, SCHED_OTHER);
  // The line runs: SYNC every 20 ms, 40 of them on the bus (waited for), never a stall.
  line.spy().clear();
  EXPECT_GE(line.spy().wait_count(0x080, 40).size(), 40u);
  EXPECT_LT(syncs(line.spy().frames()).second, 1000.0);
  EXPECT_TRUE(line.bridge().running());
}
