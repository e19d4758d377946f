#include "dds/fastdds_log.hpp"

#include <array>
#include <chrono>
#include <memory>
#include <string_view>

#include <spdlog/spdlog.h>

#include "base/log_rate.hpp"
#include "base/repeat_log.hpp"

namespace lb::ddsl {

namespace fdds = eprosima::fastdds::dds;

namespace {

// A warning Fast DDS gives for a condition every secured participant goes through, not a fault:
// DDS Security's crypto plugin drops what a participant just discovered sends until their keys
// are exchanged, and the sender sends it again (reliable) once they are. Fast DDS 2.9.1 warns
// for each such submessage: 104-109 lines a secured demo run, up to 1,600 a second at a client's
// first call. Said once, as what it is, then counted and said again at most every 10 minutes.
struct Expected {
  std::string_view category;
  std::string_view message;
  std::string_view why;
};
constexpr std::array kExpected{
    Expected{"SECURITY_CRYPTO", "No key material yet",
             "expected while the keys of a participant just discovered are being exchanged (DDS Security's first "
             "moments): what it sent is dropped and sent again once they are"},
};
constexpr std::chrono::seconds kExpectedInterval = std::chrono::minutes(10);

// Fast DDS calls consumers from its one logging thread, so the rates need no lock.
class SpdlogConsumer final : public fdds::LogConsumer {
 public:
  void Consume(const fdds::Log::Entry& entry) override {
    const char* category = entry.context.category != nullptr ? entry.context.category : "?";
    for (std::size_t i = 0; i < kExpected.size(); ++i) {
      const auto& e = kExpected[i];
      if (category != e.category || std::string_view(entry.message).substr(0, e.message.size()) != e.message) continue;
      auto& repeat = expected_[i];
      if (!repeat.allow(e.message)) return;
      spdlog::info("Fast DDS [{}] {}: {}{}", category, e.message, e.why, repeat.note());
      return;
    }
    auto& kind = entry.kind == fdds::Log::Kind::Error     ? errors_
                 : entry.kind == fdds::Log::Kind::Warning ? warnings_
                                                          : infos_;
    if (!kind.rate.allow()) return;
    spdlog::log(kind.level, "Fast DDS [{}] {}{}", category, entry.message, held_back_note(kind.rate));
  }

 private:
  std::array<RepeatLog, kExpected.size()> expected_{RepeatLog(kExpectedInterval)};
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
