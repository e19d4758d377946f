// --lock-memory (the packaged bus unit runs with it): the bus process's pages never go to swap,
// and locking costs what the process uses, not the whole of every mapping. Locked in full, each
// thread's stack (RLIMIT_STACK, 8 MiB by default) was faulted in and pinned: 149.5 MB resident at
// 8 x 30 saws against 26-34 MB unlocked (issue 27).
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <chrono>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>

#include "msgs/sawPubSubTypes.h"
#include "support/line_harness.hpp"
#include "support/simulated_saw.hpp"

using namespace std::chrono_literals;

namespace {

// The kB and count fields of /proc/<pid>/status ("VmLck:  1234 kB" -> 1234).
std::map<std::string, long> proc_status(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::map<std::string, long> fields;
  std::string line;
  while (std::getline(in, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos) continue;
    std::istringstream value(line.substr(colon + 1));
    long n = 0;
    if (value >> n) fields[line.substr(0, colon)] = n;
  }
  return fields;
}

}  // namespace

TEST(LockMemory, TheBusProcessLocksWhatItUsesNotEveryThreadStack) {
  rlimit stack{};
  ASSERT_EQ(::getrlimit(RLIMIT_STACK, &stack), 0);
  if (stack.rlim_cur == RLIM_INFINITY || stack.rlim_cur < 4u * 1024 * 1024)
    GTEST_SKIP() << "RLIMIT_STACK is " << stack.rlim_cur << ": thread stacks are not the 8 MiB this test tells apart";
  const long stack_kb = static_cast<long>(stack.rlim_cur / 1024);

  lb::test::LineHarness line("lockmem", 14);
  // linebridge's own arguments, then --lock-memory (sh passes them on: $0 is the bridge).
  line.set_bridge_launcher({"/bin/sh", "-c", "exec \"$0\" \"$@\" --lock-memory"});
  line.start(lb::test::simulated_saw("b"));
  // The lock comes before the buses start: a saw booted and operational ran on locked memory.
  line.operational_status<linebridge_msgs::msg::SawStatusPubSubType>("saw1");
  if (line.bridge().log().find("--lock-memory: mlockall refused") != std::string::npos)
    GTEST_SKIP() << "this machine refuses mlockall (no CAP_IPC_LOCK, RLIMIT_MEMLOCK): " << line.logs();
  ASSERT_TRUE(line.bridge().wait_log("memory locked", 10s)) << line.logs();

  const auto s = proc_status(line.bridge().pid());
  ASSERT_TRUE(s.contains("VmLck") && s.contains("RssAnon") && s.contains("Threads")) << "no /proc status fields";
  std::cout << "bus process with --lock-memory: VmLck " << s.at("VmLck") << " kB, RssAnon " << s.at("RssAnon")
            << " kB, " << s.at("Threads") << " threads\n";
  EXPECT_GT(s.at("VmLck"), 0) << "mlockall said it locked, and the kernel counts nothing locked";
  // Every thread's stack resident would alone be Threads x stack_kb of anonymous memory; the
  // process with its stacks locked as used holds far less than half of that (1 x 1 measured:
  // RssAnon about 11.6 MB, 7 threads).
  EXPECT_LT(s.at("RssAnon"), s.at("Threads") * stack_kb / 2)
      << "VmLck " << s.at("VmLck") << " kB, RssAnon " << s.at("RssAnon") << " kB, " << s.at("Threads") << " threads of "
      << stack_kb << " kB stacks: the stacks were locked in full\n"
      << line.logs();
}
