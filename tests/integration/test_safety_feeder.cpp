// The safety table's column for the CiA 414-2 1.1 feeder box: every row of test_safety_table.cpp, on
// its own executable so that ctest runs the columns in parallel.
#include "support/safety_table.hpp"

namespace lb::test::safety {

INSTANTIATE_TEST_SUITE_P(Feeder, SafetyOnTheBus, ::testing::Values(&feeder()), column_name);

}  // namespace lb::test::safety
