#pragma once
// Runs an executable to its end and returns its exit code and output (stdout and stderr merged),
// for tests of what a command prints and how it exits. Bounded: killed after `timeout`.

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace lb::test {

struct CommandResult {
  int exit_code = -1;  // -1: killed by a signal (or the timeout)
  std::string output;
};

inline CommandResult run_command(std::vector<std::string> argv, std::chrono::seconds timeout = std::chrono::seconds(60)) {
  static int counter = 0;
  const std::string log = ::testing::TempDir() + "/cmd_" + std::to_string(::getpid()) + "_" + std::to_string(++counter) + ".log";
  std::vector<char*> args;
  for (auto& a : argv) args.push_back(a.data());
  args.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  pid_t pid = -1;
  CommandResult r;
  if (posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ) != 0) {
    posix_spawn_file_actions_destroy(&actions);
    r.output = "cannot start " + argv.front();
    return r;
  }
  posix_spawn_file_actions_destroy(&actions);
  int status = 0;
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (::waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > end) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(log);
  std::stringstream s;
  s << in.rdbuf();
  r.output = s.str();
  return r;
}

}  // namespace lb::test
