#include "app/dds_supervisor.hpp"

#include <spawn.h>
#include <spdlog/spdlog.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <string>

#include "app/arguments.hpp"
#include "app/run_until_signal.hpp"

extern char** environ;

namespace lb::app {
namespace {
constexpr std::chrono::milliseconds kFirstPause{100};
constexpr std::chrono::milliseconds kLongestPause{5000};

struct SpawnAttributes {
  SpawnAttributes() { posix_spawnattr_init(&value); }
  ~SpawnAttributes() { posix_spawnattr_destroy(&value); }
  SpawnAttributes(const SpawnAttributes&) = delete;
  SpawnAttributes& operator=(const SpawnAttributes&) = delete;
  posix_spawnattr_t value{};
};
}  // namespace

DdsSupervisor::DdsSupervisor(std::vector<std::string> argv, std::function<std::uint64_t()> served)
    : argv_(std::move(argv)), served_(std::move(served)) {
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string v(*e);
    // The parent is the service: a child that spoke to systemd would be refused (NotifyAccess=main)
    // or, worse, be taken for it.
    if (v.starts_with("NOTIFY_SOCKET=") || v.starts_with("WATCHDOG_USEC=") || v.starts_with("WATCHDOG_PID=") ||
        v.starts_with(std::string(kBusPidEnv) + "="))
      continue;
    env_.push_back(v);
  }
  // The child ends with this process (die_with_bus_process(), called first thing by a DDS side).
  env_.push_back(std::string(kBusPidEnv) + "=" + std::to_string(::getpid()));
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
  std::vector<char*> args;
  for (auto& a : argv_) args.push_back(a.data());
  args.push_back(nullptr);
  std::vector<char*> envp;
  for (auto& e : env_) envp.push_back(e.data());
  envp.push_back(nullptr);
  // posix_spawn, not fork: it does not copy this process's page tables nor make its memory
  // copy-on-write, so the running bus loops take no copy-on-write faults while a DDS process
  // starts. (With fork, SYNC gaps of 61-85 ms were seen at the DDS process's start at 8 x 30
  // devices; whether the fork or the child's start beside the loops caused them was not isolated.)
  // Its own process group: a terminal's Ctrl-C reaches this process, which tells the channel and
  // then ends its DDS process itself, instead of the child ending first and reading as lost.
  SpawnAttributes attr;
  posix_spawnattr_setflags(&attr.value, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attr.value, 0);
  pid_t pid = -1;
  if (const int rc = ::posix_spawn(&pid, args[0], nullptr, &attr.value, args.data(), envp.data()); rc != 0) {
    errno = rc;
    return -1;
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

bool die_with_bus_process() {
  const char* bus = std::getenv(kBusPidEnv);
  if (bus == nullptr) return true;  // not a supervised child (systemd's unit, a test)
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  return std::to_string(::getppid()) == bus;  // else the bus process died before the prctl
}

}  // namespace lb::app
