#pragma once
// The safety table of issue 40: every registered device type (a column, the test's parameter:
// safety_device.hpp) x every event (a row, one TEST_P of test_safety_table.cpp), each row on a line
// of its own (safety_line.hpp) and judged from the bus and the DDS answers (safety_judge.hpp).
// One executable per column (test_safety_<column>.cpp instantiates the rows for its type), so
// ctest runs the columns' rows in parallel.

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <ostream>
#include <string>

#include "support/safety_device.hpp"
#include "support/safety_judge.hpp"
#include "support/safety_line.hpp"

namespace lb::test::safety {

class SafetyOnTheBus : public ::testing::TestWithParam<const SafetyDevice*> {
 protected:
  const SafetyDevice& device() const { return *GetParam(); }
  SafetyLine& line() { return *line_; }

  // The line running: the device operational, the operator's enabling set value accepted and on
  // the bus (the rows judge what becomes of it).
  void start(RowOptions options = {});
  // The enabling set value of start() and the kept values written after it: a bridge killed now
  // restarts from them.
  void await_kept();
  // The device booted up after `after_ns`, was NMT-started after that, and says operational.
  bool started_again(std::int64_t after_ns);
  // The bus went on for a second: what the bridge sends at a start is recorded.
  void settle();
  // The device was heard (a frame of its own within its heartbeat timeout) at `ns`.
  bool heard_at(std::int64_t ns);
  // After an event: the operator runs the device again if its enabling level is off, then stops it
  // three ways: the stopping command, the enabling level off, NMT stop.
  void operator_stops();
  // The invariants over everything recorded; one failure per violation.
  void judge();
  // A bridge restart: killed, started, its run announced and its DDS side reached.
  void restart_bridge(const std::string& extra_keys = "");

  std::unique_ptr<SafetyLine> line_;
  std::string kept_before_;  // the bridge's state_dir before start()'s enabling set value
};

// The column's name where gtest prints the parameter (and ctest lists it).
inline void PrintTo(const SafetyDevice* device, std::ostream* os) { *os << device->column; }

inline std::string column_name(const ::testing::TestParamInfo<const SafetyDevice*>& info) { return info.param->column; }

}  // namespace lb::test::safety
