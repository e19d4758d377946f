#pragma once
// The bridge's log off its bus loops: spdlog's default logger replaced by an asynchronous one
// with a bounded queue, so a bus loop never waits for stdout (journald's socket under systemd,
// a pipe nobody reads, a slow disk): a line is handed over, and when the queue is full the oldest
// waiting line is dropped and counted (diagnostics: log_lines_dropped) instead. The key events'
// lines (base/journal_event) take the same queue; under systemd its thread sends them to the
// journal with their fields (app/journal_sink). For the life of main; the destructor writes what
// waits and puts a synchronous logger back.

#include <cstddef>
#include <cstdint>
#include <string>

namespace lb::app {

class AsyncLog {
 public:
  // The bus process's boot logs about 2,200 lines at once at 8 buses x 30 saws; the DDS process
  // logs a few lines a minute, and each queued line is a preallocated 400-byte slot (8192 of
  // them were 3.3 MB resident in a process that never used them).
  static constexpr std::size_t kBusQueue = 8192;  // lines
  static constexpr std::size_t kDdsQueue = 512;
  AsyncLog(std::string pattern, std::size_t queue_lines);
  ~AsyncLog();
  AsyncLog(const AsyncLog&) = delete;
  AsyncLog& operator=(const AsyncLog&) = delete;

 private:
  std::string pattern_;
};

// Lines dropped because the queue was full, since start (0 without an AsyncLog).
std::uint64_t log_lines_dropped();

}  // namespace lb::app
