// The rows of the safety table (issue 40, point 5): each event on a line of one device of the
// column's type, the real bridge and simulator processes on a virtual bus, judged from the frames
// and the DDS answers by the invariants of safety_judge.hpp (I1 no enabling level after a start
// until an operator sets one, I2 every stop answered and on the bus within 100 ms, I3 a value
// switched off is not replaced). The columns: test_safety_<type>.cpp.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "support/safety_table.hpp"

namespace msg = linebridge_msgs::msg;
namespace srv = linebridge_msgs::srv;
using namespace std::chrono_literals;

namespace lb::test::safety {

// ---- the fixture's steps ----

void SafetyOnTheBus::start(RowOptions options) {
  ASSERT_NE(std::getenv("LINEBRIDGE_NETNS"), nullptr) << "run through launch_scripts/netns-run.sh (ctest does)";
  line_ = std::make_unique<SafetyLine>(device(), options);
  line_->start();
  kept_before_ = line_->kept();
  const auto on = line_->set_enabling(true);
  ASSERT_TRUE(on.accepted) << "the operator's enabling set value was refused: " << on.reason << "\n" << line_->logs();
  for (const auto& e : device().enabling) {
    ASSERT_TRUE(line_->frame_after(on.written_ns, e.enabled))
        << "never on the bus: " << e.what << " (the row would judge nothing)\n"
        << line_->logs();
  }
}

void SafetyOnTheBus::await_kept() {
  // Not an assertion: the rows judge the bus, whatever the bridge keeps; without this wait a
  // restart could race the store and test less than it says.
  (void)line_->kept_changed(kept_before_);
}

bool SafetyOnTheBus::started_again(std::int64_t after_ns) {
  const auto& d = device();
  return eventually(30s, [&] {
    std::int64_t boot_up = 0, started = 0;
    for (const auto& f : line_->spy().frames()) {
      if (f.timestamp_ns <= after_ns) continue;
      if (boot_up == 0) {
        if (f.id == d.heartbeat_id() && f.len >= 1 && f.data[0] == 0) boot_up = f.timestamp_ns;
      } else if (started == 0) {
        if (f.id == 0 && f.len == 2 && f.data[0] == 0x01 && (f.data[1] == d.node || f.data[1] == 0))
          started = f.timestamp_ns;
      } else if (f.id == d.heartbeat_id() && f.len >= 1 && f.data[0] == 0x05) {
        return true;
      }
    }
    return false;
  });
}

void SafetyOnTheBus::settle() { ASSERT_TRUE(line_->bus_past(bus_now_ns() + 1'000'000'000)) << "the bus went quiet"; }

bool SafetyOnTheBus::heard_at(std::int64_t ns) {
  // As the judge counts it: by the bridge's bus process running then, from frames it could hear.
  const SafetyJudge judge(device(), line_->options().heartbeat_timeout_ms, line_->t0(), {line_->bridge_runs(), {}});
  return judge.heard(by_stamp(line_->spy().frames()), ns, ns) != nullptr;
}

void SafetyOnTheBus::operator_stops() {
  if (!line_->enabling_on_bus()) {
    // The operator runs it again, so that the stops below have something to stop.
    const auto on = line_->set_enabling(true);
    if (on.accepted)
      (void)line_->frame_after(
          on.written_ns, [this](const auto& f) { return device().enabled(f); }, 5s);
  }
  line_->press_stop();
  line_->set_enabling(false);
  line_->nmt(srv::NMT_STOP);
}

void SafetyOnTheBus::judge() {
  // Everything sent up to now is recorded once a frame stamped later is.
  ASSERT_TRUE(line_->bus_past(bus_now_ns() + 300'000'000)) << "the bus went quiet";
  const SafetyJudge judge(device(), line_->options().heartbeat_timeout_ms, line_->t0(), {line_->bridge_runs(), {}});
  const auto frames = by_stamp(line_->spy().frames());
  const auto violations = judge.judge(frames, line_->requests());
  std::cout << "[ safety   ] " << device().column << ", the operator's stops:\n"
            << judge.stop_times(frames, line_->requests());
  for (const auto& v : violations) ADD_FAILURE() << v.invariant << ": " << v.text;
  if (violations.empty()) return;
  std::string requests;
  for (const auto& r : line_->requests()) requests += "  " + judge.request(r) + "\n";
  std::string spoofed;
  for (const auto& s : line_->spoofed()) {
    auto f = s.frame;
    f.timestamp_ns = s.sent_ns;
    spoofed += " " + judge.frame(f);
  }
  ADD_FAILURE() << "the operator's requests:\n"
                << requests << "spoofed:" << (spoofed.empty() ? " none" : spoofed) << "\n"
                << device().name << " now: " << line_->node_text() << "\n"
                << line_->logs(40);
}

void SafetyOnTheBus::restart_bridge(const std::string& extra_keys) {
  const auto run = line_->run();
  const auto matches = line_->panel().matches();
  line_->kill_bridge();
  if (!extra_keys.empty()) line_->write_bridge_config(extra_keys);
  line_->start_bridge();
  ASSERT_TRUE(line_->await_run(run, matches)) << "the restarted bridge never reached DDS\n" << line_->logs();
}

namespace {

bool operational(const msg::NodeDiagnostics& n) { return n.node_state() == "operational"; }

}  // namespace

// ---- the rows ----

// The device alone loses power (its simulator killed and started again) while the bridge runs: it
// comes back pre-operational with its power-on values, and nothing enables it but the operator.
TEST_P(SafetyOnTheBus, DeviceAlonePowerCycled) {
  ASSERT_NO_FATAL_FAILURE(start());
  const auto cut = bus_now_ns();
  line().kill_device();
  line().start_device();
  ASSERT_TRUE(started_again(cut)) << "never started again after its power cycle\n" << line().logs();
  ASSERT_NO_FATAL_FAILURE(settle());
  operator_stops();
  judge();
}

// The bridge alone is killed and started again (same state_dir) while the device runs: the device
// is found running and keeps what it had; the operator's stops reach it.
TEST_P(SafetyOnTheBus, BridgeRestartedWithTheDeviceRunning) {
  ASSERT_NO_FATAL_FAILURE(start());
  await_kept();
  ASSERT_NO_FATAL_FAILURE(restart_bridge());
  ASSERT_TRUE(line().wait_node(line().run(), operational)) << line().node_text() << "\n" << line().logs();
  ASSERT_NO_FATAL_FAILURE(settle());
  operator_stops();
  judge();
}

// A power cut: the bridge and the device go down together and come back together.
TEST_P(SafetyOnTheBus, PowerCut) {
  ASSERT_NO_FATAL_FAILURE(start());
  await_kept();
  const auto run = line().run();
  const auto matches = line().panel().matches();
  line().kill_bridge();
  line().kill_device();
  const auto cut = bus_now_ns();
  line().start_device();
  line().start_bridge();
  ASSERT_TRUE(line().await_run(run, matches)) << "the restarted bridge never reached DDS\n" << line().logs();
  ASSERT_TRUE(started_again(cut)) << "never started again after the power cut\n" << line().logs();
  ASSERT_NO_FATAL_FAILURE(settle());
  operator_stops();
  judge();
}

// The operator resets the device (NMT reset node): it boots up anew, a start like a power cycle.
TEST_P(SafetyOnTheBus, OperatorNmtReset) {
  ASSERT_NO_FATAL_FAILURE(start());
  const auto reset = line().nmt(srv::NMT_RESET_NODE);
  ASSERT_TRUE(reset.accepted) << "the operator's reset was refused: " << reset.reason << "\n" << line().logs();
  ASSERT_TRUE(started_again(reset.written_ns)) << "never started again after the reset\n" << line().logs();
  ASSERT_NO_FATAL_FAILURE(settle());
  operator_stops();
  judge();
}

// The bridge restarts while the device runs, with a line file whose identity for the device's
// node is wrong (1018h sub 2 product code 0BADBAD0h): its boot fails, it runs on unmanaged, and
// the operator's stops still reach it (design rule 4: whatever the identity check says).
TEST_P(SafetyOnTheBus, BootFailsWithTheDeviceRunning) {
  ASSERT_NO_FATAL_FAILURE(start());
  await_kept();
  ASSERT_NO_FATAL_FAILURE(restart_bridge("    identity: {product_code: 0x0BADBAD0}\n"));
  ASSERT_TRUE(line().wait_node(line().run(), [](const auto& n) { return !n.boot_error().code().empty(); }))
      << "the boot never failed: " << line().node_text() << "\n"
      << line().logs();
  ASSERT_NO_FATAL_FAILURE(settle());
  operator_stops();
  judge();
}

// A stop sent while a restarted bridge boots the running device: the device stalls at the boot's
// first SDO request after it answered one of the new bridge's (its process stopped: a device slow
// to answer; heartbeat timeout 8 s, SDO timeout 10 s, so the new bridge has heard it, still does,
// and the boot is still under way) until the new bridge's DDS side is reached; the operator
// switches the enabling level off and presses the stopping command; the device is resumed and the
// boot ends. Both stops go out at once, and from then on no RPDO carries the enabling level: the
// kept values do not undo them. (Stalled at the very first request, the device may not have sent
// anything since the new bridge opened the bus: not heard, its stops rightly refused.)
TEST_P(SafetyOnTheBus, StopWhileARestartedBridgeBootsTheDevice) {
  ASSERT_NO_FATAL_FAILURE(start({.heartbeat_timeout_ms = 8000, .sdo_timeout_ms = 10000}));
  await_kept();
  const auto run = line().run();
  const auto matches = line().panel().matches();
  line().kill_bridge();
  const auto restart = bus_now_ns();
  // Shared with the spy's thread, which stalls the device within the frame's time.
  auto stalled = std::make_shared<std::atomic<std::int64_t>>(0);
  auto answered = std::make_shared<std::int64_t>(0);  // the device's first SDO answer to the new bridge
  const pid_t pid = line().device_pid();
  const auto request = device().sdo_request_id();
  const auto answer = 0x580u + static_cast<std::uint32_t>(device().node);
  line().spy().watch([stalled, answered, pid, request, answer, restart](const lb::can::CanFrame& f) {
    if (*stalled != 0 || f.timestamp_ns <= restart) return;
    if (f.id == answer && *answered == 0) {
      *answered = f.timestamp_ns;
    } else if (f.id == request && *answered != 0) {
      ::kill(pid, SIGSTOP);
      *stalled = f.timestamp_ns;
    }
  });
  line().start_bridge();
  const bool boot_began = eventually(30s, [&] { return *stalled != 0; });
  line().spy().watch({});
  ASSERT_TRUE(boot_began) << "the restarted bridge never asked the device twice (a request, its answer, a request)\n"
                          << line().logs();
  const bool reached = line().await_run(run, matches);
  if (!reached) line().resume_device();
  ASSERT_TRUE(reached) << "the restarted bridge never reached DDS\n" << line().logs();
  for (const auto& f : line().spy().frames()) {
    ASSERT_FALSE(f.timestamp_ns > restart && f.id == 0 && f.len == 2 && f.data[0] == 0x01 && f.data[1] == device().node)
        << "the boot ended before the stops could be sent: the row would judge nothing\n"
        << line().logs();
  }
  const auto off = line().set_enabling(false);
  const auto stop = line().press_stop();
  line().resume_device();
  for (const auto* r : {&off, &stop}) {
    EXPECT_TRUE(heard_at(r->written_ns)) << "the device was not heard by the new bridge at '" << r->what
                                         << "' (stalled too long?): the row proves less";
  }
  ASSERT_TRUE(line().wait_node(line().run(), operational)) << line().node_text() << "\n" << line().logs();
  ASSERT_NO_FATAL_FAILURE(settle());
  line().press_stop();
  line().nmt(srv::NMT_STOP);
  judge();
}

// A PDO change on a running device: the bridge restarts with a line file whose PDO parameter the
// device does not hold (a TPDO's transmission type); with the default pdo_change_when_running:
// pre_operational the device may be paused to write it; started again, it gets no enabling level.
TEST_P(SafetyOnTheBus, PdoChangeOnARunningDevice) {
  // A heartbeat timeout of 1 s: the restarted bridge hears the running device before it writes
  // (it judges "running" from a heartbeat within that time, even on a loaded machine).
  ASSERT_NO_FATAL_FAILURE(start({.heartbeat_timeout_ms = 1000}));
  await_kept();
  const auto restart = bus_now_ns();
  ASSERT_NO_FATAL_FAILURE(restart_bridge(device().pdo_change));
  const auto index = device().pdo_change_index;
  const auto sub = device().pdo_change_sub;
  const auto request = device().sdo_request_id();
  ASSERT_TRUE(line().frame_after(restart,
                                 [&](const lb::can::CanFrame& f) {
                                   return f.id == request && f.len == 8 && (f.data[0] & 0xE0) == 0x20 &&
                                          f.data[1] == (index & 0xFF) && f.data[2] == (index >> 8) && f.data[3] == sub;
                                 }))
      << "the restarted bridge never wrote the changed PDO parameter: the row would judge nothing\n"
      << line().logs();
  ASSERT_TRUE(line().wait_node(line().run(), operational)) << line().node_text() << "\n" << line().logs();
  ASSERT_NO_FATAL_FAILURE(settle());
  operator_stops();
  judge();
}

// The device's heartbeat is lost (its process stopped for longer than its heartbeat timeout) and
// comes back (resumed: it was operational all along).
TEST_P(SafetyOnTheBus, HeartbeatLostAndBack) {
  ASSERT_NO_FATAL_FAILURE(start());
  line().stall_device();
  const bool lost = line().wait_node(0, [](const auto& n) { return !n.online(); });
  line().resume_device();
  ASSERT_TRUE(lost) << "the bridge never missed the stalled device\n" << line().logs();
  ASSERT_TRUE(line().wait_node(0, [](const auto& n) { return n.online() && n.node_state() == "operational"; }))
      << line().node_text() << "\n"
      << line().logs();
  ASSERT_NO_FATAL_FAILURE(settle());
  operator_stops();
  judge();
}

// Spoofed (a): 10 pairs of a boot-up and a pre-operational heartbeat on the device's heartbeat
// identifier (70Xh#00, 70Xh#7F), 100 ms apart, next to the running device. The stops sent during
// them (the stopping command, the level off) and a second after them (the same and NMT stop) are
// taken: the device is heard running all along.
TEST_P(SafetyOnTheBus, SpoofedBootUpsAndPreOperationalHeartbeats) {
  ASSERT_NO_FATAL_FAILURE(start());
  Spoofer::Schedule schedule;
  for (int i = 0; i < 10; ++i) {
    schedule.push_back({std::chrono::milliseconds(100 * i), lb::can::make_frame(device().heartbeat_id(), {0x00})});
    schedule.push_back({std::chrono::milliseconds(100 * i + 50), lb::can::make_frame(device().heartbeat_id(), {0x7F})});
  }
  Spoofer spoofer(line(), schedule);
  ASSERT_TRUE(spoofer.sent(6));
  std::vector<OperatorRequest> stops;
  stops.push_back(line().press_stop());
  stops.push_back(line().set_enabling(false));
  ASSERT_TRUE(spoofer.done());
  ASSERT_NO_FATAL_FAILURE(settle());
  stops.push_back(line().press_stop());
  stops.push_back(line().set_enabling(false));
  stops.push_back(line().nmt(srv::NMT_STOP));
  for (const auto& r : stops) {
    EXPECT_TRUE(heard_at(r.written_ns)) << "the device was not heard at '" << r.what << "': the row proves less";
  }
  judge();
}

// Spoofed (b): 10 SYNCs over about 200 ms (25 ms apart), then one every 4.5 s for 20 s. The stops
// sent meanwhile are taken and on the bus at once.
TEST_P(SafetyOnTheBus, SpoofedSyncs) {
  ASSERT_NO_FATAL_FAILURE(start());
  Spoofer::Schedule schedule;
  for (int i = 0; i < 10; ++i) schedule.push_back({std::chrono::milliseconds(25 * i), lb::can::make_frame(0x080, {})});
  for (int i = 1; i <= 4; ++i)
    schedule.push_back({std::chrono::milliseconds(225 + 4500 * i), lb::can::make_frame(0x080, {})});
  Spoofer spoofer(line(), schedule);
  ASSERT_TRUE(spoofer.sent(10));
  ASSERT_TRUE(line().bus_past(bus_now_ns() + 300'000'000)) << "the bus went quiet";
  const auto stop = line().press_stop();
  ASSERT_TRUE(spoofer.sent(11));
  const auto off = line().set_enabling(false);
  ASSERT_TRUE(spoofer.sent(13));
  const auto nmt_stop = line().nmt(srv::NMT_STOP);
  ASSERT_TRUE(spoofer.done());
  for (const auto* r : {&stop, &off, &nmt_stop}) {
    EXPECT_TRUE(heard_at(r->written_ns)) << "the device was not heard at '" << r->what << "': the row proves less";
  }
  judge();
}

// Spoofed (c): one SDO download setting the device's 1017h (producer heartbeat time) to 0, on a
// line without heartbeat_producer_ms: the device confirms it and sends no more heartbeats, but runs
// on (its TPDOs, SDO answers: it is heard). The stops are taken and on the bus at once.
TEST_P(SafetyOnTheBus, SpoofedHeartbeatProducerOff) {
  ASSERT_NO_FATAL_FAILURE(start());
  const auto n = static_cast<std::uint32_t>(device().node);
  const auto sent = bus_now_ns();
  line().spoof(lb::can::make_frame(0x600 + n, {0x2B, 0x17, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00}));
  ASSERT_TRUE(line().frame_after(sent,
                                 [n](const lb::can::CanFrame& f) {
                                   return f.id == 0x580 + n && f.len >= 4 && f.data[0] == 0x60 && f.data[1] == 0x17 &&
                                          f.data[2] == 0x10 && f.data[3] == 0x00;
                                 }))
      << "the device never confirmed the spoofed 1017h write\n"
      << line().logs();
  // Three heartbeat timeouts later: the bridge has judged the silence (or written 1017h back).
  const auto timeout = std::int64_t{line().options().heartbeat_timeout_ms} * 1'000'000;
  ASSERT_TRUE(line().bus_past(bus_now_ns() + 3 * timeout)) << "the bus went quiet";
  const auto stop = line().press_stop();
  const auto off = line().set_enabling(false);
  const auto nmt_stop = line().nmt(srv::NMT_STOP);
  for (const auto* r : {&stop, &off, &nmt_stop}) {
    EXPECT_TRUE(heard_at(r->written_ns)) << "the device was not heard at '" << r->what << "': the row proves less";
  }
  judge();
}

}  // namespace lb::test::safety
