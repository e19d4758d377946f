#pragma once
// What the SocketCAN tests need around the code under test: shell commands (ip, tc, cansend) and
// candump -l as an independent recorder. Only meaningful where vcan0 exists (launch_scripts/vcan-run.sh).

#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "can/candump_log.hpp"
#include "support/child_process.hpp"

namespace lb::test {

// Exit status of a shell command (-1 when it did not exit normally).
inline int sh(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

inline bool cansend(const std::string& ifname, const std::string& frame) {
  return sh("cansend " + ifname + " " + frame) == 0;
}

// `candump -l <if>` (every frame, error frames too) in a directory of its own; stop() ends it (SIGTERM makes candump
// flush and close its file) and the frames come from the file it wrote, parsed as a log: bus parses them.
class Candump {
 public:
  explicit Candump(const std::string& ifname, std::chrono::milliseconds settle = std::chrono::milliseconds(800)) {
    dir_ = ::testing::TempDir() + "/candump-" + std::to_string(::getpid()) + "-" +
           std::to_string(std::chrono::steady_clock::now().time_since_epoch().count());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    proc_ = std::make_unique<ChildProcess>(
        std::vector<std::string>{"/bin/sh", "-c", "cd '" + dir_ + "' && exec candump -l " + ifname + ",0:0,#FFFFFFFF"},
        dir_ + "/stderr.txt");
    std::this_thread::sleep_for(settle);  // candump has opened and bound its socket
  }
  void stop() {
    if (proc_) proc_->stop();
  }
  // The log file candump wrote (candump-<date>.log).
  std::string path() const {
    for (const auto& e : std::filesystem::directory_iterator(dir_)) {
      if (e.path().extension() == ".log") return e.path().string();
    }
    return {};
  }
  std::vector<can::LogRecord> records() {
    stop();
    std::vector<can::LogRecord> out;
    std::ifstream in(path());
    for (std::string line; std::getline(in, line);) {
      auto r = can::parse_log_line(line);
      if (r && *r) out.push_back(**r);
    }
    return out;
  }
  std::string text() {
    stop();
    std::ifstream in(path());
    return std::string(std::istreambuf_iterator<char>(in), {});
  }

 private:
  std::string dir_;
  std::unique_ptr<ChildProcess> proc_;
};

}  // namespace lb::test
