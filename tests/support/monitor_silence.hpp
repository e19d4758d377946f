#pragma once
// What a monitor-role bridge must show in its own diagnostics: it hears its bus and never sends on
// it. A transmit on a monitor bus is refused and counted in tx_dropped, so a send attempt shows
// there too (the refusal itself is logged only at debug level). Read from a snapshot taken after
// everything the test did: two diagnostics samples after now.

#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "msgs/commonPubSubTypes.h"
#include "support/collector.hpp"

namespace lb::test {

inline void expect_monitor_never_sent(Collector<linebridge_msgs::msg::DiagnosticsPubSubType>& diag,
                                      const std::string& logs) {
  const std::size_t diag_seen = diag.size();
  ASSERT_TRUE(diag.wait(std::chrono::seconds(10), [diag_seen](const auto& v) { return v.size() >= diag_seen + 2; }))
      << logs;
  const auto snapshot = diag.samples().back();
  ASSERT_EQ(snapshot.buses().size(), 1u);
  EXPECT_EQ(snapshot.buses()[0].role(), "monitor");
  EXPECT_GT(snapshot.buses()[0].frames_in(), 0u) << "the snapshot is not of the bus the bridge monitors";
  EXPECT_EQ(snapshot.buses()[0].tx_dropped(), 0u) << "the bridge tried to transmit\n" << logs;
  EXPECT_EQ(snapshot.buses()[0].frames_out(), 0u) << logs;
}

}  // namespace lb::test
