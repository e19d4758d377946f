#include "app/dds_supervisor.hpp"

#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstring>

#include "app/arguments.hpp"
#include "app/run_until_signal.hpp"

extern char** environ;

namespace lb::app {
namespace {
constexpr std::chrono::milliseconds kFirstPause{100};
constexpr std::chrono::milliseconds kLongestPause{5000};
}  // namespace

DdsSupervisor::DdsSupervisor(std::vector<std::string> argv, std::function<std::uint64_t()> served)
    : argv_(std::move(argv)), served_(std::move(served)) {
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string v(*e);
    // The parent is the service: a child that spoke to systemd would be refused (NotifyAccess=main)
    // or, worse, be taken for it.
    if (v.starts_with("NOTIFY_SOCKET=") || v.starts_with("WATCHDOG_USEC=") || v.starts_with("WATCHDOG_PID=")) continue;
    env_.push_back(v);
  }
  thread_ = std::thread([this] { run(); });
}

DdsSupervisor::~DdsSupervisor() {
  pid_t pid = 0;
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    pid = child_.load();
  }
  cv_.notify_all();
  if (pid > 0) {
    ::kill(pid, SIGTERM);
    std::unique_lock lock(mutex_);
    if (!cv_.wait_for(lock, std::chrono::seconds(2), [this] { return child_.load() == 0; })) ::kill(pid, SIGKILL);
  }
  thread_.join();
}

pid_t DdsSupervisor::spawn() {
  // Everything the child needs is built before fork(): after it, a multithreaded process may call
  // only async-signal-safe functions.
  std::vector<char*> args;
  for (auto& a : argv_) args.push_back(a.data());
  args.push_back(nullptr);
  std::vector<char*> envp;
  for (auto& e : env_) envp.push_back(e.data());
  envp.push_back(nullptr);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(1);  // the parent died between fork and prctl
    // A terminal's Ctrl-C reaches the whole foreground group: this process stops its DDS process
    // itself (SIGTERM) after telling its channel, so the child ignores SIGINT instead of ending
    // first and reading as lost.
    struct sigaction ignore {};
    ignore.sa_handler = SIG_IGN;
    ::sigaction(SIGINT, &ignore, nullptr);
    ::execve(args[0], args.data(), envp.data());
    ::_exit(127);
  }
  return pid;
}

void DdsSupervisor::run() {
  auto pause = kFirstPause;
  while (true) {
    const auto served_before = served_();
    const pid_t pid = spawn();
    if (pid < 0) {
      spdlog::error("cannot start the DDS process: {}", std::strerror(errno));
    } else {
      {
        std::lock_guard lock(mutex_);
        child_ = pid;
        if (stop_) ::kill(pid, SIGTERM);  // the destructor came before it knew this child
      }
      spdlog::info("DDS process started (pid {})", pid);
      int status = 0;
      while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      std::lock_guard lock(mutex_);
      child_ = 0;
      cv_.notify_all();
      if (stop_) return;
      if (WIFEXITED(status) && WEXITSTATUS(status) == kExitUsage) {
        spdlog::critical("the DDS process refused the configuration (exit 2): not restarted");
        refused_ = true;
        request_stop();
        return;
      }
      spdlog::warn("DDS process (pid {}) {} {}; the bus runs on, a new DDS process starts", pid,
                   WIFSIGNALED(status) ? "killed by signal" : "exited with",
                   WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status));
    }
    // One that served is replaced at once; one that keeps ending at start-up waits, so a crash loop
    // does not cost the bus side its CPU.
    if (pid > 0 && served_() > served_before) {
      pause = kFirstPause;
      continue;
    }
    std::unique_lock lock(mutex_);
    if (cv_.wait_for(lock, pause, [this] { return stop_; })) return;
    pause = std::min<std::chrono::milliseconds>(pause * 2, kLongestPause);
  }
}

}  // namespace lb::app
