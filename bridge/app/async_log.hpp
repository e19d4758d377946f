#pragma once
// The bridge's log off its bus loops: spdlog's default logger replaced by an asynchronous one
// with a bounded queue, so a bus loop never waits for stdout (journald's socket under systemd,
// a pipe nobody reads, a slow disk): a line is handed over, and when the queue is full the oldest
// waiting line is dropped and counted (diagnostics: log_lines_dropped) instead. For the life of
// main; the destructor writes what waits and puts a synchronous logger back.

#include <cstddef>
#include <cstdint>
#include <string>

namespace lb::app {

class AsyncLog {
 public:
  static constexpr std::size_t kQueue = 8192;  // lines
  explicit AsyncLog(std::string pattern);
  ~AsyncLog();
  AsyncLog(const AsyncLog&) = delete;
  AsyncLog& operator=(const AsyncLog&) = delete;

 private:
  std::string pattern_;
};

// Lines dropped because the queue was full, since start (0 without an AsyncLog).
std::uint64_t log_lines_dropped();

}  // namespace lb::app
