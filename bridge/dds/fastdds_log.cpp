#include "dds/fastdds_log.hpp"

#include <memory>

#include <spdlog/spdlog.h>

#include "base/log_rate.hpp"

namespace lb::ddsl {

namespace fdds = eprosima::fastdds::dds;

namespace {

// Fast DDS calls consumers from its one logging thread, so the rates need no lock.
class SpdlogConsumer final : public fdds::LogConsumer {
 public:
  void Consume(const fdds::Log::Entry& entry) override {
    auto& kind = entry.kind == fdds::Log::Kind::Error     ? errors_
                 : entry.kind == fdds::Log::Kind::Warning ? warnings_
                                                          : infos_;
    if (!kind.rate.allow()) return;
    spdlog::log(kind.level, "Fast DDS [{}] {}{}", entry.context.category != nullptr ? entry.context.category : "?",
                entry.message, held_back_note(kind.rate));
  }

 private:
  struct Kind {
    spdlog::level::level_enum level;
    LogRate rate{5};
  };
  Kind errors_{spdlog::level::err};
  Kind warnings_{spdlog::level::warn};
  Kind infos_{spdlog::level::debug};
};

}  // namespace

FastDdsLogRoute::FastDdsLogRoute(fdds::Log::Kind verbosity) {
  fdds::Log::ClearConsumers();
  fdds::Log::RegisterConsumer(std::make_unique<SpdlogConsumer>());
  fdds::Log::SetVerbosity(verbosity);
}

FastDdsLogRoute::~FastDdsLogRoute() {
  fdds::Log::Flush();
  // Back to Fast DDS's defaults (its stdout consumer, errors only): nothing of Fast DDS's can
  // reach spdlog after this object.
  fdds::Log::Reset();
}

}  // namespace lb::ddsl
