#include "app/journal_sink.hpp"

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <systemd/sd-journal.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>

namespace lb::app {

JournalSink::JournalSink(std::shared_ptr<spdlog::sinks::sink> out, Send send, std::string identifier)
    : out_(std::move(out)),
      send_(std::move(send)),
      identifier_(std::move(identifier)),
      formatter_(std::make_unique<spdlog::pattern_formatter>()) {}

std::shared_ptr<JournalSink> JournalSink::for_stdout() {
  return std::make_shared<JournalSink>(std::make_shared<spdlog::sinks::stdout_color_sink_mt>(),
                                       stdout_is_journal() ? Send(send_to_journal) : Send(),
                                       program_invocation_short_name);
}

void JournalSink::log(const spdlog::details::log_msg& msg) {
  if (send_) {
    if (const auto event = journal::decode(msg)) {
      if (send_(journal_fields(formatted(msg), msg.level, *event, identifier_)) >= 0) return;
      // Not lost: the plain line, which the journal's stream takes.
      journal_failures_.fetch_add(1, std::memory_order_relaxed);
    }
  }
  out_->log(msg);
}

std::string JournalSink::formatted(const spdlog::details::log_msg& msg) {
  spdlog::memory_buf_t buf;
  {
    std::lock_guard lock(mutex_);
    formatter_->format(msg, buf);
  }
  std::string text(buf.data(), buf.size());
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  return text;
}

void JournalSink::flush() { out_->flush(); }

void JournalSink::set_pattern(const std::string& pattern) {
  {
    std::lock_guard lock(mutex_);
    formatter_ = std::make_unique<spdlog::pattern_formatter>(pattern);
  }
  out_->set_pattern(pattern);
}

void JournalSink::set_formatter(std::unique_ptr<spdlog::formatter> formatter) {
  {
    std::lock_guard lock(mutex_);
    formatter_ = formatter->clone();
  }
  out_->set_formatter(std::move(formatter));
}

bool is_journal_stream(const char* journal_stream, int fd) {
  if (journal_stream == nullptr) return false;
  const std::string_view s(journal_stream);
  const auto colon = s.find(':');
  if (colon == std::string_view::npos) return false;
  unsigned long long dev = 0;
  unsigned long long ino = 0;
  const auto d = std::from_chars(s.data(), s.data() + colon, dev);
  const auto i = std::from_chars(s.data() + colon + 1, s.data() + s.size(), ino);
  if (d.ec != std::errc() || d.ptr != s.data() + colon || i.ec != std::errc() || i.ptr != s.data() + s.size())
    return false;
  struct stat st {};
  if (::fstat(fd, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == dev && static_cast<unsigned long long>(st.st_ino) == ino;
}

// stdout, not stderr: the log writes to stdout (under the package's units both are the one stream).
bool stdout_is_journal() { return is_journal_stream(std::getenv("JOURNAL_STREAM"), STDOUT_FILENO); }

int syslog_priority(spdlog::level::level_enum level) {
  switch (level) {
    case spdlog::level::trace:
    case spdlog::level::debug: return 7;
    case spdlog::level::info: return 6;
    case spdlog::level::warn: return 4;
    case spdlog::level::err: return 3;
    case spdlog::level::critical: return 2;
    case spdlog::level::off:
    case spdlog::level::n_levels: break;
  }
  return 6;
}

std::vector<std::string> journal_fields(std::string_view message, spdlog::level::level_enum level,
                                        const journal::Decoded& event, std::string_view identifier) {
  std::vector<std::string> fields;
  fields.reserve(event.fields.size() + 4);
  fields.push_back("MESSAGE=" + std::string(message));
  fields.push_back("PRIORITY=" + std::to_string(syslog_priority(level)));
  fields.push_back("MESSAGE_ID=" + std::string(event.kind->message_id));
  fields.push_back("SYSLOG_IDENTIFIER=" + std::string(identifier));
  for (const auto& [name, value] : event.fields) fields.push_back(name + "=" + value);
  return fields;
}

int send_to_journal(const std::vector<std::string>& fields) {
  std::vector<iovec> iov;
  iov.reserve(fields.size());
  for (const auto& f : fields) iov.push_back({const_cast<char*>(f.data()), f.size()});  // NOLINT: iovec's API
  return sd_journal_sendv(iov.data(), static_cast<int>(iov.size()));
}

}  // namespace lb::app
