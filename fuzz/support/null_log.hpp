#pragma once
// Fuzz targets log every message (so the formatting of hostile values is exercised too) into a
// sink that keeps nothing: the fuzzer's output stays readable and no time goes to the terminal.

#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include <memory>

namespace lb::fuzz {

inline void log_to_nowhere() {
  auto logger = std::make_shared<spdlog::logger>("fuzz", std::make_shared<spdlog::sinks::null_sink_mt>());
  logger->set_level(spdlog::level::trace);
  spdlog::set_default_logger(std::move(logger));
}

}  // namespace lb::fuzz
