// The safety table's column for the CiA 420-4 3.1 saw: every row of test_safety_table.cpp, on
// its own executable so that ctest runs the columns in parallel.
#include "support/safety_table.hpp"

namespace lb::test::safety {

INSTANTIATE_TEST_SUITE_P(Saw31, SafetyOnTheBus, ::testing::Values(&saw31()), column_name);

}  // namespace lb::test::safety
