#pragma once
// Runs an executable to its end and returns its exit code and output (stdout and stderr merged),
// for tests of what a command prints and how it exits. Bounded: killed after `timeout`.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "support/child_process.hpp"

namespace lb::test {

struct CommandResult {
  int exit_code = -1;  // -1: ended by a signal (or the timeout)
  std::string output;
};

inline CommandResult run_command(std::vector<std::string> argv,
                                 std::chrono::seconds timeout = std::chrono::seconds(60)) {
  static int counter = 0;
  const std::string log = ::testing::TempDir() + "/cmd_" + std::to_string(::getpid()) + "_" +
                          std::to_string(++counter) + ".log";
  ChildProcess p(std::move(argv), log);
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (p.running() && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const int status = p.stop();  // the wait status; SIGTERM, then SIGKILL, if the timeout passed
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, p.log()};
}

}  // namespace lb::test
