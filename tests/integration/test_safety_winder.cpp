// The safety table's column for the example winder (test-only type): every row of test_safety_table.cpp, on
// its own executable so that ctest runs the columns in parallel.
#include "support/safety_table.hpp"

namespace lb::test::safety {

INSTANTIATE_TEST_SUITE_P(Winder, SafetyOnTheBus, ::testing::Values(&winder()), column_name);

}  // namespace lb::test::safety
