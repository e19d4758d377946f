#include "app/async_log.hpp"

#include <spdlog/async.h>
#include <spdlog/async_logger.h>
#include <spdlog/spdlog.h>

#include "app/journal_sink.hpp"

namespace lb::app {

namespace {
constexpr const char* kName = "linebridge";
}

AsyncLog::AsyncLog(std::string pattern, std::size_t queue_lines) : pattern_(std::move(pattern)) {
  const auto level = spdlog::get_level();
  spdlog::init_thread_pool(queue_lines, 1);
  // The log's thread writes the lines and, under systemd, sends the events' to the journal.
  auto sink = JournalSink::for_stdout();
  auto logger = std::make_shared<spdlog::async_logger>(kName, std::move(sink), spdlog::thread_pool(),
                                                       spdlog::async_overflow_policy::overrun_oldest);
  logger->set_level(level);
  logger->set_pattern(pattern_);
  spdlog::set_default_logger(std::move(logger));
}

AsyncLog::~AsyncLog() {
  // Synchronous again for whatever logs during the rest of the exit. The asynchronous logger is
  // held here until its queue's thread has written what waits and ended (the pool's destructor
  // joins it): so the logger is released on this thread, after the join, never by the worker.
  auto async = spdlog::default_logger();
  auto sync = std::make_shared<spdlog::logger>(std::string(kName) + "-exit", JournalSink::for_stdout());
  sync->set_level(spdlog::get_level());
  sync->set_pattern(pattern_);
  spdlog::set_default_logger(std::move(sync));
  spdlog::drop(kName);
  spdlog::details::registry::instance().set_tp(nullptr);
}

std::uint64_t log_lines_dropped() {
  const auto pool = spdlog::thread_pool();
  return pool ? pool->overrun_counter() : 0;
}

}  // namespace lb::app
