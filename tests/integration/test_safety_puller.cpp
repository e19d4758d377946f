// The safety table's column for the CiA 420-2 1.0 puller: every row of test_safety_table.cpp, on
// its own executable so that ctest runs the columns in parallel.
#include "support/safety_table.hpp"

namespace lb::test::safety {

INSTANTIATE_TEST_SUITE_P(Puller, SafetyOnTheBus, ::testing::Values(&puller()), column_name);

}  // namespace lb::test::safety
