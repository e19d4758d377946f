#pragma once
// How the bench script and the bench processes hand over: a process creates a file when it is
// ready, and waits for a file the script creates when everyone is ready. Files, because the script
// is bash and the processes are started in the background.

#include <chrono>
#include <fstream>
#include <string>
#include <thread>

#include <sys/stat.h>

namespace lb::bench {

inline bool file_exists(const std::string& path) {
  struct stat st {};
  return !path.empty() && ::stat(path.c_str(), &st) == 0;
}

inline void signal_file(const std::string& path) {
  if (path.empty()) return;
  const std::string tmp = path + ".tmp";
  std::ofstream(tmp) << "ready\n";
  std::rename(tmp.c_str(), path.c_str());  // appears complete or not at all
}

// True once the file exists; false after the timeout. An empty path means "do not wait".
inline bool await_file(const std::string& path, std::chrono::milliseconds timeout) {
  if (path.empty()) return true;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!file_exists(path)) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return true;
}

}  // namespace lb::bench
