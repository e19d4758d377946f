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
    const char* category = entry.context.category != nullptr ? entry.context.category : "?";
    switch (entry.kind) {
      case fdds::Log::Kind::Error:
        if (errors_.allow()) spdlog::error("Fast DDS [{}] {}{}", category, entry.message, held_back_note(errors_));
        break;
      case fdds::Log::Kind::Warning:
        if (warnings_.allow()) spdlog::warn("Fast DDS [{}] {}{}", category, entry.message, held_back_note(warnings_));
        break;
      default:
        if (infos_.allow()) spdlog::debug("Fast DDS [{}] {}{}", category, entry.message, held_back_note(infos_));
        break;
    }
  }

 private:
  LogRate errors_{5};
  LogRate warnings_{5};
  LogRate infos_{5};
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
