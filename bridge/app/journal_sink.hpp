#pragma once
// The bridge's log sink: every line to stdout as before, except that under systemd the line of a
// key event (base/journal_event: a device lost, a boot failed, an EMCY ...) goes to the journal as
// an entry of its own, with MESSAGE (the line as stdout would have it: the log's pattern, the
// line's own time among it), PRIORITY (its level),
// MESSAGE_ID (its kind's) and its fields (LB_LINE, LB_BUS, LB_DEVICE, LB_NODE, the kind's own), so
// that `journalctl MESSAGE_ID=... LB_DEVICE=saw1` finds it. It runs on the AsyncLog's thread: a bus
// loop only queues the line, as any other.
//
// "Under systemd" is: this process's stdout is the journal's stream ($JOURNAL_STREAM names
// stdout's device and inode, systemd.exec(5)). Its lines go to the journal then anyway, so an
// event sent there directly lands where its plain line would have, once. sd_booted() and the
// journal's socket would only say that the machine runs systemd: a bridge started by hand in a
// terminal, or by the tests, would then put its events where its user does not look.

#include <spdlog/sinks/sink.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "base/journal_event.hpp"

namespace lb::app {

class JournalSink final : public spdlog::sinks::sink {
 public:
  // One journal entry, each field "NAME=value" (sd_journal_sendv's contract: 0, or a negative errno).
  using Send = std::function<int(const std::vector<std::string>& fields)>;

  // Lines to `out`; event lines to `send` instead when it is set. `identifier`: SYSLOG_IDENTIFIER.
  JournalSink(std::shared_ptr<spdlog::sinks::sink> out, Send send, std::string identifier);
  // The bridge's: stdout in colour; the journal when stdout is its stream.
  static std::shared_ptr<JournalSink> for_stdout();

  void log(const spdlog::details::log_msg& msg) override;
  void flush() override;
  void set_pattern(const std::string& pattern) override;
  void set_formatter(std::unique_ptr<spdlog::formatter> formatter) override;

  bool to_journal() const { return static_cast<bool>(send_); }
  // Event lines the journal refused (written to `out` instead).
  std::uint64_t journal_failures() const { return journal_failures_.load(std::memory_order_relaxed); }

 private:
  std::string formatted(const spdlog::details::log_msg& msg);

  std::shared_ptr<spdlog::sinks::sink> out_;
  Send send_;
  std::string identifier_;
  std::mutex mutex_;                              // the formatter's
  std::unique_ptr<spdlog::formatter> formatter_;  // out_'s pattern, for MESSAGE
  std::atomic<std::uint64_t> journal_failures_{0};
};

// $JOURNAL_STREAM is "device:inode" of the stream systemd connected to stdout and stderr; true when
// it names this process's stdout (not merely inherited by a process whose stdout went elsewhere).
bool stdout_is_journal();
bool is_journal_stream(const char* journal_stream, int fd);

// syslog's priority of a level (PRIORITY=): debug 7, info 6, warning 4, error 3, critical 2.
int syslog_priority(spdlog::level::level_enum level);

// The journal entry of an event's line: `message` is the line as formatted.
std::vector<std::string> journal_fields(std::string_view message, spdlog::level::level_enum level,
                                        const journal::Decoded& event, std::string_view identifier);

// sd_journal_sendv.
int send_to_journal(const std::vector<std::string>& fields);

}  // namespace lb::app
