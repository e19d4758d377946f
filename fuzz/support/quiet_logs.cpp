// Linked into the targets whose code logs: every message is still formatted (so the formatting of
// hostile values is fuzzed too) but goes into a sink that keeps nothing, so the fuzzer's output
// stays readable and no time goes to the terminal.
#include <spdlog/sinks/null_sink.h>
#include <spdlog/spdlog.h>

#include <memory>

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  auto logger = std::make_shared<spdlog::logger>("fuzz", std::make_shared<spdlog::sinks::null_sink_mt>());
  logger->set_level(spdlog::level::trace);
  spdlog::set_default_logger(std::move(logger));
  return 0;
}
