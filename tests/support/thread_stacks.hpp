#pragma once
// The stack of every thread of the test process, for a failure that looks like a hang inside a
// library (a thread that stopped handling its socket): printed with the failure, so that one CI
// run that saw it is enough to tell where. Needs gdb (launch_scripts/setup.sh installs it).

#include <sys/prctl.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "support/run_command.hpp"

namespace lb::test {

inline std::string thread_stacks() {
  if (!std::filesystem::exists("/usr/bin/gdb")) return "(no gdb: thread stacks not taken)";
  // Yama's ptrace_scope 1 lets only an ancestor trace a process unless it names a tracer.
  ::prctl(PR_SET_PTRACER, PR_SET_PTRACER_ANY, 0, 0, 0);
  const auto r = run_command({"/usr/bin/gdb", "-p", std::to_string(::getpid()), "-batch", "-nx", "-ex",
                              "thread apply all bt 30"},
                             std::chrono::seconds(120));
  return "thread stacks (gdb, exit " + std::to_string(r.exit_code) + "):\n" + r.output;
}

}  // namespace lb::test
