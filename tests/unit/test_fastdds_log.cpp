// Fast DDS's own warnings and errors reach the bridge's log through FastDdsLogRoute, rate-limited,
// and stop reaching it when the route ends. The entries are queued through Fast DDS's logging API
// (Log::QueueLog, what its EPROSIMA_LOG_* macros call), so they pass Fast DDS's logging thread.
#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <sstream>
#include <string>
#include <thread>

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>
#include <fastdds/dds/log/Log.hpp>

#include "dds/fastdds_log.hpp"

namespace {

namespace fdds = eprosima::fastdds::dds;

class FastDdsLog : public ::testing::Test {
 protected:
  void SetUp() override {
    auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(out_);
    auto logger = std::make_shared<spdlog::logger>("test", sink);
    logger->set_pattern("%l %v");
    logger->set_level(spdlog::level::trace);
    previous_ = spdlog::default_logger();
    spdlog::set_default_logger(logger);
  }
  void TearDown() override { spdlog::set_default_logger(previous_); }

  static void queue(fdds::Log::Kind kind, const std::string& category_message) {
    // The category must outlive the entry, as the macros' string literals do.
    fdds::Log::QueueLog(category_message, fdds::Log::Context{__FILE__, __LINE__, __func__, "RTPS_MSG_IN"}, kind);
  }
  static std::size_t count(const std::string& text, const std::string& what) {
    std::size_t n = 0;
    for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
    return n;
  }

  std::ostringstream out_;
  std::shared_ptr<spdlog::logger> previous_;
};

TEST_F(FastDdsLog, WarningsAndErrorsReachTheLogWithTheirCategory) {
  {
    const lb::ddsl::FastDdsLogRoute route;
    EXPECT_EQ(fdds::Log::GetVerbosity(), fdds::Log::Kind::Warning);
    queue(fdds::Log::Kind::Warning, "Reached the maximum number of samples allowed by this reader's QoS.");
    queue(fdds::Log::Kind::Error, "Problem reserving CacheChange in reader");
    fdds::Log::Flush();
  }
  const auto text = out_.str();
  EXPECT_NE(text.find(
                "warning Fast DDS [RTPS_MSG_IN] Reached the maximum number of samples allowed by this reader's QoS."),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("error Fast DDS [RTPS_MSG_IN] Problem reserving CacheChange in reader"), std::string::npos)
      << text;
}

TEST_F(FastDdsLog, ABurstIsLoggedAFewTimesASecondWithTheCountHeldBack) {
  {
    const lb::ddsl::FastDdsLogRoute route;
    for (int i = 0; i < 50; ++i) queue(fdds::Log::Kind::Warning, "refused " + std::to_string(i));
    fdds::Log::Flush();
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));
    queue(fdds::Log::Kind::Warning, "refused once more");
    fdds::Log::Flush();
  }
  const auto text = out_.str();
  // Five a second get through; the next one, a second later, says how many were held back.
  EXPECT_EQ(count(text, "Fast DDS [RTPS_MSG_IN] refused"), 6u) << text;
  EXPECT_NE(text.find("refused once more (45 more not logged)"), std::string::npos) << text;
}

TEST_F(FastDdsLog, NothingReachesTheLogAfterTheRouteEnds) {
  { const lb::ddsl::FastDdsLogRoute route; }
  EXPECT_EQ(fdds::Log::GetVerbosity(), fdds::Log::Kind::Error);
  // Fast DDS's own consumer prints it to stdout again (seen in the test's output), not to spdlog.
  queue(fdds::Log::Kind::Error, "after the route");
  fdds::Log::Flush();
  EXPECT_EQ(out_.str().find("after the route"), std::string::npos) << out_.str();
}

}  // namespace
