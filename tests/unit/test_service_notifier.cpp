// The systemd notifications of the gateway, with real bus loops and a real notification socket:
// READY=1 once every loop runs, WATCHDOG=1 only while every loop makes progress (an idle loop
// counts, its tick wakes it), none while one loop is stalled, again once it runs; RELOADING=1, not
// STOPPING=1, when the process starts again in place.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <string>
#include <thread>

#include "app/service_notifier.hpp"
#include "can/unique_fd.hpp"
#include "canopen/bus_loop.hpp"
#include "support/notify_socket.hpp"

using namespace std::chrono_literals;
using lb::test::NotifySocket;

namespace {

std::unique_ptr<lb::canopen::BusLoop> ticking_loop(const std::string& name) {
  auto bus = lb::can::open_bus("virtual:" + name + "-" + std::to_string(::getpid()));
  EXPECT_TRUE(bus) << bus.error().message;
  auto loop = std::make_unique<lb::canopen::BusLoop>(std::move(*bus));
  loop->arm_timer(loop->create_timer([] {}), lb::app::ServiceNotifier::kLoopTick, lb::app::ServiceNotifier::kLoopTick);
  return loop;
}

TEST(ServiceNotifier, WatchdogIsFedOnlyWhileEveryLoopMakesProgress) {
  NotifySocket socket;
  ::setenv("WATCHDOG_USEC", "1000000", 1);  // checks every 500 ms
  auto busy = ticking_loop("notify-a");
  auto idle = ticking_loop("notify-b");
  lb::app::ServiceNotifier notifier(
      {{"a", [&] { return busy->iterations(); }}, {"b", [&] { return idle->iterations(); }}});
  ::unsetenv("WATCHDOG_USEC");
  EXPECT_EQ(notifier.watchdog(), 1s);
  EXPECT_EQ(socket.next(300ms), "") << "ready before the loops run";
  busy->start();
  idle->start();
  EXPECT_EQ(socket.next(2s).rfind("READY=1", 0), 0U);
  EXPECT_EQ(socket.next(2s), "WATCHDOG=1") << "two running loops, one of them idle";

  // A handler that blocks the loop for 2.5 s: no ping while it does.
  busy->post([] { std::this_thread::sleep_for(2500ms); });
  socket.during(600ms);  // pings queued so far, and a check that still saw progress may ping
  EXPECT_EQ(socket.during(1500ms).find("WATCHDOG=1"), std::string::npos);
  EXPECT_EQ(socket.next(3s), "WATCHDOG=1") << "the loop runs again";

  notifier.stopping();
  EXPECT_NE(socket.during(700ms).find("STOPPING=1"), std::string::npos);
  busy->stop();
  idle->stop();
}

// A process that starts again in place (a bridge that stepped back re-executes itself, the same
// PID): RELOADING=1 with why as the status, never STOPPING=1 (systemd would wait TimeoutStopSec for
// an exit that never comes, then kill the new image), and a last ping for the new image's start.
TEST(ServiceNotifier, StartingAgainInPlaceIsNoStop) {
  NotifySocket socket;
  auto loop = ticking_loop("notify-d");
  lb::app::ServiceNotifier notifier({{"d", [&] { return loop->iterations(); }}});
  loop->start();
  const auto ready = socket.next(2s);
  EXPECT_EQ(ready.rfind("READY=1\n", 0), 0U) << ready;
  EXPECT_NE(ready.find("WATCHDOG=1"), std::string::npos) << "READY=1 is a ping too: " << ready;
  notifier.restarting("another master won the bus: starting again as a standby");
  EXPECT_EQ(socket.next(2s), "RELOADING=1\nWATCHDOG=1\nSTATUS=another master won the bus: starting again as a standby");
  EXPECT_EQ(socket.during(300ms).find("STOPPING=1"), std::string::npos);
  loop->stop();
}

TEST(ServiceNotifier, NothingWithoutSystemd) {
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
  auto loop = ticking_loop("notify-c");
  lb::app::ServiceNotifier notifier({{"c", [&] { return loop->iterations(); }}});
  EXPECT_EQ(notifier.watchdog().count(), 0);
  loop->start();
  std::this_thread::sleep_for(200ms);
  notifier.stopping();  // harmless
  loop->stop();
}

}  // namespace
