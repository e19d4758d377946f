// MandatoryDevices on a virtual bus, driven by hand: heartbeats from a spy, the boot's facts told
// as the boot tells them (RemoteNode::starting, then the hold or the start it sends). NMT frames
// expected from CiA 301: id 000h, byte 0 01h start / 02h stop, byte 1 the node-ID.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <future>
#include <string>
#include <thread>

#include "canopen/bus_loop.hpp"
#include "canopen/remote_node.hpp"
#include "gateways/node/mandatory_devices.hpp"
#include "support/bus_spy.hpp"

using namespace std::chrono_literals;
namespace co = lb::canopen;
using lb::gateways::MandatoryDevices;

namespace {

constexpr std::uint8_t kSaw = 5;     // mandatory
constexpr std::uint8_t kPuller = 3;  // not

class Line {
 public:
  explicit Line(MandatoryDevices::Policy policy)
      : uri_("virtual:mandatory-" + std::to_string(::getpid()) + "-" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name()),
        spy_(uri_),
        loop_(lb::can::open_bus(uri_).value()),
        saw_(loop_, kSaw, 300ms, true),
        puller_(loop_, kPuller, 300ms, true),
        mandatory_(loop_, "bus b", policy,
                   {{"saw1", &saw_, true, [] { return false; }}, {"puller1", &puller_, false, [] { return false; }}}) {
    loop_.start();
  }
  ~Line() {
    beating_saw_ = false;
    heartbeats_ = {};
    loop_.stop();
  }

  // Runs f on the loop thread and returns its result.
  template <class F>
  auto on_loop(F f) {
    std::promise<decltype(f())> p;
    auto fut = p.get_future();
    loop_.post([&] {
      if constexpr (std::is_void_v<decltype(f())>) {
        f();
        p.set_value();
      } else {
        p.set_value(f());
      }
    });
    return fut.get();
  }
  // Both devices send heartbeats (the saw's can be silenced) in the state the master last told them.
  void beat() {
    heartbeats_ = std::jthread([this](std::stop_token stop) {
      while (!stop.stop_requested()) {
        if (beating_saw_) (void)spy_.send(lb::can::make_frame(0x700 + kSaw, {state(kSaw)}));
        (void)spy_.send(lb::can::make_frame(0x700 + kPuller, {state(kPuller)}));
        std::this_thread::sleep_for(50ms);
      }
    });
  }
  // beat(), then both devices are seen online (a fatal failure if not).
  void beat_until_both_online() {
    beat();
    ASSERT_TRUE(online(puller_));
    ASSERT_TRUE(online(saw_));
  }
  std::uint8_t state(std::uint8_t node) {
    std::uint8_t s = ran_before_ ? 0x05 : 0x7F;
    for (const auto& f : spy_.frames(0x000)) {
      if (f.len == 2 && f.data[1] == node) s = f.data[0] == 0x01 ? 0x05 : f.data[0] == 0x02 ? 0x04 : 0x7F;
    }
    return s;
  }
  // What BootSequence::start does once every check passed: tell the listeners, then the hold or NMT start.
  void boot_passes(co::RemoteNode& node) {
    on_loop([&] {
      node.starting({false, false, {}});
      if (const auto hold = node.operator_hold()) {
        (void)node.command(*hold);
      } else {
        (void)node.command(co::NmtCommand::start);
      }
      node.set_configured(true);
    });
  }
  // From here on, seen() looks only at NMT frames sent later (the devices' states still follow all of them).
  void mark() { since_ = spy_.frames(0x000).size(); }
  bool seen(std::uint8_t command, std::uint8_t node, std::chrono::milliseconds deadline = 3s) {
    const auto end = std::chrono::steady_clock::now() + deadline;
    do {
      const auto f = spy_.frames(0x000);
      if (std::any_of(f.begin() + static_cast<std::ptrdiff_t>(std::min(since_, f.size())), f.end(),
                      [&](const lb::can::CanFrame& x) {
                        return x.len == 2 && x.data[0] == command && x.data[1] == node;
                      })) {
        return true;
      }
      std::this_thread::sleep_for(10ms);
    } while (std::chrono::steady_clock::now() < end);
    return false;
  }
  bool online(co::RemoteNode& node, bool online = true) {
    const auto end = std::chrono::steady_clock::now() + 3s;
    while (on_loop([&] { return node.online(); }) != online) {
      if (std::chrono::steady_clock::now() > end) return false;
      std::this_thread::sleep_for(10ms);
    }
    return true;
  }
  // Any NMT frame since mark() within the window (none is the expectation where it is used).
  bool any_nmt(std::chrono::milliseconds window) {
    std::this_thread::sleep_for(window);
    return spy_.frames(0x000).size() > since_;
  }
  // What NodeStateMachine::take_over does for a device it hears operational (the master before
  // started it): adopted as it runs, without a frame, and its drivers told so.
  void adopt_running(co::RemoteNode& node) {
    on_loop([&] {
      node.adopt(co::NmtState::operational);
      node.starting({true, false, {}, true});
    });
  }
  // A standby that heard the line run (both online, the puller operational) takes it over while
  // the mandatory saw is silent: the saw is not adopted (it gets its boot), the puller is adopted
  // as it runs.
  void take_over_with_the_saw_silent() {
    on_loop([&] { mandatory_.stand_by(); });
    ran_before_ = true;
    ASSERT_NO_FATAL_FAILURE(beat_until_both_online());
    beating_saw_ = false;
    ASSERT_TRUE(online(saw_, false));
    on_loop([&] { mandatory_.mastering(); });
    adopt_running(puller_);
  }
  // A boot attempt that ended failed, as BootSequence reports a device that does not answer
  // (CiA 302-2 error B: no answer to 1000h).
  void boot_fails(co::RemoteNode& node) {
    on_loop([&] {
      co::BootReport report;
      report.error = co::BootError{'B', "device type", 0x1000, 0, "", "", 0, "no answer to the read of 1000h"};
      node.tell([&](co::NodeDriver& d) { d.on_boot(report); });
    });
  }

  std::string uri_;
  lb::test::BusSpy spy_;
  co::BusLoop loop_;
  co::RemoteNode saw_, puller_;
  MandatoryDevices mandatory_;
  std::atomic<bool> beating_saw_{true};
  // Another master started both devices before this test's line looks at them (a standby's case):
  // they report operational until this line commands otherwise.
  std::atomic<bool> ran_before_{false};
  std::jthread heartbeats_;
  std::size_t since_ = 0;
};

}  // namespace

// The puller's boot passes first: it is held pre-operational (not started) until the mandatory saw
// passed; then the saw is started and the puller after it. The saw's heartbeat is lost: the
// puller gets NMT stop and is kept stopped (its next boot stops it again) also after the saw's
// boot passes again; an operator's start releases it.
TEST(MandatoryDevices, WaitForTheMandatoryOneThenStopTheOthersWhenItIsLost) {
  Line line(MandatoryDevices::Policy::stop_others);
  ASSERT_NO_FATAL_FAILURE(line.beat_until_both_online());

  line.boot_passes(line.puller_);
  EXPECT_EQ(line.on_loop([&] { return line.puller_.operator_hold(); }), co::NmtCommand::enter_pre_operational);
  EXPECT_EQ(line.on_loop([&] { return line.mandatory_.missing(); }), std::vector<std::string>{"saw1"});
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.hold_of(1); }).find("waiting for mandatory device saw1"),
            std::string::npos);
  EXPECT_FALSE(line.seen(0x01, kPuller, 300ms)) << "started before the mandatory saw passed";

  line.boot_passes(line.saw_);
  ASSERT_TRUE(line.seen(0x01, kSaw));
  ASSERT_TRUE(line.seen(0x01, kPuller)) << "not started once the mandatory saw passed";
  EXPECT_TRUE(line.on_loop([&] { return line.mandatory_.missing().empty() && line.mandatory_.state().empty(); }));
  EXPECT_FALSE(line.on_loop([&] { return line.puller_.operator_hold().has_value(); }));
  {
    const auto f = line.spy_.frames(0x000);  // nothing marked yet: every NMT frame since the start
    const auto saw = std::find_if(f.begin(), f.end(),
                                  [](const lb::can::CanFrame& x) { return x.data[0] == 0x01 && x.data[1] == kSaw; });
    const auto puller = std::find_if(f.begin(), f.end(), [](const lb::can::CanFrame& x) {
      return x.data[0] == 0x01 && x.data[1] == kPuller;
    });
    EXPECT_LT(saw - f.begin(), puller - f.begin()) << "the puller was started before the mandatory saw";
  }

  line.beating_saw_ = false;  // lost after 300 ms
  ASSERT_TRUE(line.seen(0x02, kPuller, 5s)) << "the puller runs on without the mandatory saw";
  EXPECT_EQ(line.on_loop([&] { return line.puller_.operator_hold(); }), co::NmtCommand::stop);
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.state(); }).find("stop_others"), std::string::npos);

  // The saw comes back and passes its boot: the puller is not started by itself, and a boot of
  // the puller now keeps it stopped.
  line.mark();
  line.beating_saw_ = true;
  ASSERT_TRUE(line.online(line.saw_));
  line.boot_passes(line.saw_);
  ASSERT_TRUE(line.seen(0x01, kSaw));
  line.boot_passes(line.puller_);
  EXPECT_FALSE(line.seen(0x01, kPuller, 500ms)) << "the puller was started again without an operator";
  EXPECT_TRUE(line.seen(0x02, kPuller)) << "the puller's boot did not keep it stopped";
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.hold_of(1); }).find("nmt start releases it"), std::string::npos);

  // The operator starts it (what DeviceServices::nmt does): released.
  line.on_loop([&] {
    (void)line.puller_.command(co::NmtCommand::start);
    line.puller_.release_hold();
    line.mandatory_.operator_command(1, co::NmtCommand::start);
  });
  EXPECT_TRUE(line.seen(0x01, kPuller));
  EXPECT_TRUE(line.on_loop([&] { return line.mandatory_.hold_of(1).empty() && line.mandatory_.state().empty(); }));
}

// report_only: the start-up wait, then a lost mandatory device is only reported.
TEST(MandatoryDevices, ReportOnlyStopsNothing) {
  Line line(MandatoryDevices::Policy::report_only);
  ASSERT_NO_FATAL_FAILURE(line.beat_until_both_online());
  line.boot_passes(line.puller_);
  EXPECT_FALSE(line.seen(0x01, kPuller, 300ms));
  line.boot_passes(line.saw_);
  ASSERT_TRUE(line.seen(0x01, kPuller));
  line.beating_saw_ = false;
  const auto end = std::chrono::steady_clock::now() + 5s;
  while (line.on_loop([&] { return line.mandatory_.missing().empty(); })) {
    ASSERT_LT(std::chrono::steady_clock::now(), end) << "the saw was never lost";
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_FALSE(line.seen(0x02, kPuller, 500ms)) << "report_only stopped the puller";
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.state(); }).find("report_only"), std::string::npos);
  // A boot of the puller now starts it: report_only waits only at start-up.
  line.mark();
  line.boot_passes(line.puller_);
  EXPECT_TRUE(line.seen(0x01, kPuller));
}

// A line's stop kept from before the bridge restarted (HoldKeeper::restore, then kept_stop, before
// the loop runs): the puller's boot puts it back in stopped even once the mandatory saw passed,
// the gate does not start it, diagnostics say the hold is from before the restart, and an
// operator's start releases it.
TEST(MandatoryDevices, ALinesStopKeptFromBeforeTheRestartHoldsUntilAnOperatorStarts) {
  Line line(MandatoryDevices::Policy::stop_others);
  // Before the loop runs, as the wiring does (the loop has started in Line: the same on its thread).
  line.on_loop([&] {
    line.mandatory_.kept_stop(1, {lb::gateways::KeptHold::Holder::line_stop, 1700000000,
                                  "mandatory device saw1 its heartbeat was lost"});
  });
  EXPECT_EQ(line.on_loop([&] { return line.puller_.operator_hold(); }), co::NmtCommand::stop);
  ASSERT_NO_FATAL_FAILURE(line.beat_until_both_online());
  line.boot_passes(line.saw_);
  ASSERT_TRUE(line.seen(0x01, kSaw));
  line.boot_passes(line.puller_);
  EXPECT_TRUE(line.seen(0x02, kPuller)) << "the puller's boot did not put it back in stopped";
  EXPECT_FALSE(line.seen(0x01, kPuller, 500ms)) << "the puller held since before the restart was started";
  const auto hold = line.on_loop([&] { return line.mandatory_.hold_of(1); });
  EXPECT_EQ(hold,
            "stopped: mandatory device saw1 its heartbeat was lost (kept from before the bridge restarted; held since "
            "2023-11-14 22:13:20 UTC); an operator's nmt start releases it");
  EXPECT_EQ(line.on_loop([&] { return line.mandatory_.line_hold(1).kind; }),
            lb::gateways::HoldKeeper::LineHold::Kind::stopped);
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.state(); }).find("puller1 (since before the bridge restarted)"),
            std::string::npos);

  line.on_loop([&] {
    (void)line.puller_.command(co::NmtCommand::start);
    line.puller_.release_hold();
    line.mandatory_.operator_command(1, co::NmtCommand::start);
  });
  EXPECT_TRUE(line.seen(0x01, kPuller));
  EXPECT_TRUE(line.on_loop([&] { return line.mandatory_.hold_of(1).empty() && line.mandatory_.state().empty(); }));
  EXPECT_EQ(line.on_loop([&] { return line.mandatory_.line_hold(1).kind; }),
            lb::gateways::HoldKeeper::LineHold::Kind::none);
}

// A standby (docs/redundancy.md) that takes over a line whose mandatory saw runs: while it stands
// by, a loss of the saw changes nothing (the master of the moment judges the line); the saw comes
// back and runs, and at the takeover both are adopted as they run (the saw first, as the takeover
// does): not one NMT frame, nothing held, nothing missing. From then on the rule holds as on a
// master bus: the saw's loss stops the puller.
TEST(MandatoryDevices, AStandbyTakesARunningLineOverWithTheMandatoryDevicePassed) {
  Line line(MandatoryDevices::Policy::stop_others);
  line.on_loop([&] { line.mandatory_.stand_by(); });
  line.ran_before_ = true;
  ASSERT_NO_FATAL_FAILURE(line.beat_until_both_online());
  line.beating_saw_ = false;  // lost while the other master runs the line
  ASSERT_TRUE(line.online(line.saw_, false));
  EXPECT_TRUE(line.on_loop([&] { return line.mandatory_.missing().empty(); }));
  EXPECT_EQ(line.on_loop([&] { return line.mandatory_.state(); }).rfind("standing by", 0), 0u);
  line.beating_saw_ = true;
  ASSERT_TRUE(line.online(line.saw_));
  EXPECT_FALSE(line.any_nmt(300ms)) << "a standby sent NMT";

  line.on_loop([&] { line.mandatory_.mastering(); });
  line.adopt_running(line.saw_);
  line.adopt_running(line.puller_);
  EXPECT_FALSE(line.any_nmt(500ms)) << "the takeover of a running line sent NMT";
  EXPECT_TRUE(line.on_loop([&] { return line.mandatory_.missing().empty() && line.mandatory_.state().empty(); }));
  EXPECT_FALSE(line.on_loop([&] { return line.puller_.operator_hold().has_value(); }));
  EXPECT_TRUE(line.on_loop([&] { return line.mandatory_.hold_of(1).empty(); }));

  line.beating_saw_ = false;  // lost under the new master
  ASSERT_TRUE(line.seen(0x02, kPuller, 5s)) << "the puller runs on without the mandatory saw";
  EXPECT_EQ(line.on_loop([&] { return line.puller_.operator_hold(); }), co::NmtCommand::stop);
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.state(); }).find("stop_others"), std::string::npos);
}

// The mandatory saw is silent at the takeover; the puller runs. The puller is adopted as it runs
// and not stopped, nor held, by the takeover (the master before let it run); the saw gets its
// boot and is missing meanwhile. Its boot fails: when_mandatory_fails: stop_others stops the
// puller then, as on a master bus.
TEST(MandatoryDevices, AtATakeoverASilentMandatoryDeviceStopsTheOthersOnlyWhenItsBootFails) {
  Line line(MandatoryDevices::Policy::stop_others);
  ASSERT_NO_FATAL_FAILURE(line.take_over_with_the_saw_silent());
  EXPECT_FALSE(line.any_nmt(500ms)) << "the takeover sent NMT";
  EXPECT_FALSE(line.on_loop([&] { return line.puller_.operator_hold().has_value(); })) << "held by the takeover";
  EXPECT_TRUE(line.on_loop([&] { return line.mandatory_.hold_of(1).empty(); }));
  EXPECT_EQ(line.on_loop([&] { return line.mandatory_.missing(); }), std::vector<std::string>{"saw1"});

  line.boot_fails(line.saw_);
  ASSERT_TRUE(line.seen(0x02, kPuller)) << "the puller runs on though the mandatory saw failed its boot";
  EXPECT_EQ(line.on_loop([&] { return line.puller_.operator_hold(); }), co::NmtCommand::stop);
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.hold_of(1); }).find("mandatory device saw1 its boot failed"),
            std::string::npos);
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.state(); }).find("stop_others"), std::string::npos);
}

// The same with report_only: the saw's failed boot is reported, the puller adopted running is not
// stopped.
TEST(MandatoryDevices, AtATakeoverReportOnlyStopsNothingWhenTheMandatoryBootFails) {
  Line line(MandatoryDevices::Policy::report_only);
  ASSERT_NO_FATAL_FAILURE(line.take_over_with_the_saw_silent());
  line.boot_fails(line.saw_);
  EXPECT_FALSE(line.any_nmt(500ms)) << "report_only stopped the puller";
  EXPECT_NE(line.on_loop([&] { return line.mandatory_.state(); }).find("report_only"), std::string::npos);
}

// A device not running at the takeover (its boot follows, as for any device not heard operational)
// waits for the mandatory saw, which is not heard then either: configured and kept
// pre-operational, started only after the saw passed its boot.
TEST(MandatoryDevices, AtATakeoverADeviceNotRunningWaitsForTheMandatoryBoot) {
  Line line(MandatoryDevices::Policy::stop_others);
  line.on_loop([&] { line.mandatory_.stand_by(); });
  ASSERT_NO_FATAL_FAILURE(line.beat_until_both_online());  // both pre-operational: nothing runs
  line.on_loop([&] { line.mandatory_.mastering(); });
  line.boot_passes(line.puller_);
  EXPECT_EQ(line.on_loop([&] { return line.puller_.operator_hold(); }), co::NmtCommand::enter_pre_operational);
  EXPECT_FALSE(line.seen(0x01, kPuller, 300ms)) << "started before the mandatory saw passed";
  line.boot_passes(line.saw_);
  ASSERT_TRUE(line.seen(0x01, kSaw));
  ASSERT_TRUE(line.seen(0x01, kPuller)) << "not started once the mandatory saw passed";
  EXPECT_TRUE(line.on_loop([&] { return line.mandatory_.missing().empty() && line.mandatory_.state().empty(); }));
}
