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

#include <fmt/format.h>

#include "app/arguments.hpp"
#include "app/run_until_signal.hpp"

extern char** environ;

namespace lb::app {
namespace {
constexpr std::chrono::milliseconds kFirstUnservedPause{100};
constexpr std::chrono::milliseconds kLongestUnservedPause{5000};

struct SpawnAttributes {
  SpawnAttributes() { posix_spawnattr_init(&value); }
  ~SpawnAttributes() { posix_spawnattr_destroy(&value); }
  SpawnAttributes(const SpawnAttributes&) = delete;
  SpawnAttributes& operator=(const SpawnAttributes&) = delete;
  posix_spawnattr_t value{};
};
}  // namespace

DdsSupervisor::DdsSupervisor(std::vector<std::string> argv, std::function<std::uint64_t()> served, Report report,
                             RestartPacing pacing)
    : argv_(std::move(argv)), served_(std::move(served)), report_(std::move(report)), pacer_(pacing) {
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

namespace {

std::string exit_text(int status) {
  if (WIFSIGNALED(status)) return "was killed by signal " + std::to_string(WTERMSIG(status));
  const int code = WEXITSTATUS(status);
  if (code == kExitUsage) return "exited with 2 (it refused the configuration: its log says why)";
  return "exited with " + std::to_string(code);
}

}  // namespace

void DdsSupervisor::run() {
  auto unserved_pause = kFirstUnservedPause;
  while (true) {
    const auto served_before = served_();
    pacer_.started(RestartPacer::Clock::now());
    const pid_t pid = spawn();
    int status = 0;
    if (pid < 0) {
      spdlog::error("cannot start the DDS process: {}", std::strerror(errno));
    } else {
      {
        std::lock_guard lock(mutex_);
        child_ = pid;
        if (stop_) ::kill(pid, SIGTERM);  // the destructor came before it knew this child
      }
      spdlog::info("DDS process started (pid {})", pid);
      while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
      }
      std::lock_guard lock(mutex_);
      child_ = 0;
      cv_.notify_all();
      if (stop_) return;
    }
    const bool served = pid > 0 && served_() > served_before;
    const bool refused = pid > 0 && WIFEXITED(status) && WEXITSTATUS(status) == kExitUsage;
    if (refused && served_() == 0) {
      // Never served: the line file or a security file is wrong from the start, as --check says.
      spdlog::critical("the DDS process refused the configuration (exit 2) before any DDS process served: not "
                       "restarted, the bridge stops");
      if (report_) report_(pid, exit_text(status) + "; not restarted, the bridge stops");
      refused_ = true;
      request_stop();
      return;
    }
    // A crash loop must not cost the bus side its CPU, and must not end the DDS side for good
    // either: the back-off, and at least the start-up pause for one that never got served or
    // refused (starting again at once helps neither).
    auto pause = pacer_.next_pause(RestartPacer::Clock::now());
    if (served && !refused) {
      unserved_pause = kFirstUnservedPause;
    } else {
      pause = std::max<std::chrono::milliseconds>(pause, unserved_pause);
      unserved_pause = std::min<std::chrono::milliseconds>(unserved_pause * 2, kLongestUnservedPause);
    }
    const auto next = pause.count() == 0
                          ? std::string("a new DDS process starts")
                          : fmt::format("the next starts in {:.1f} s", std::chrono::duration<double>(pause).count());
    if (pid > 0) {
      const auto text = exit_text(status);
      if (refused) {
        // It served before: a certificate, grant or CRL that expired since, found at this start.
        spdlog::critical("DDS process (pid {}) {}; the bus runs on without DDS, {} (back-off up to {} s)", pid, text,
                         next, std::chrono::duration_cast<std::chrono::seconds>(pacer_.pacing().longest_pause).count());
      } else {
        spdlog::warn("DDS process (pid {}) {}; the bus runs on, {}{}", pid, text, next,
                     pacer_.step() > 0
                         ? fmt::format(" ({} starts in the last {} s: back-off)",
                                       pacer_.starts_within(RestartPacer::Clock::now()), pacer_.pacing().window.count())
                         : std::string());
      }
      if (report_) report_(pid, text + "; " + next);
    }
    if (pause.count() == 0) continue;
    std::unique_lock lock(mutex_);
    if (cv_.wait_for(lock, pause, [this] { return stop_; })) return;
  }
}

bool die_with_bus_process() {
  const char* bus = std::getenv(kBusPidEnv);
  if (bus == nullptr) return true;  // not a supervised child (systemd's unit, a test)
  ::prctl(PR_SET_PDEATHSIG, SIGKILL);
  return std::to_string(::getppid()) == bus;  // else the bus process died before the prctl
}

}  // namespace lb::app
