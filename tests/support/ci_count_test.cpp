// The CI-count helper (tests/support/ci_count.hpp): which count a test runs, and the binomial tail
// its reduced-count bounds are chosen with. Reference values are closed forms (P(X > n-1) = p^n,
// P(X > 0) = 1 - (1-p)^n) and a textbook figure: P(Bin(10, 0.05) >= 3) = 0.01150.
#include "tests/support/ci_count.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>

namespace imucal::test_support {
namespace {

TEST(CiCount, TheTestsOwnVariableWinsThenWholeCountsThenTheCiCount) {
  ::unsetenv("IMUCAL_WHOLE_COUNTS");
  ::unsetenv("IMUCAL_CI_COUNT_TEST_N");
  EXPECT_EQ(test_count("IMUCAL_CI_COUNT_TEST_N", 10, 40), 10);
  EXPECT_EQ(test_count(nullptr, 10, 40), 10);
  ::setenv("IMUCAL_WHOLE_COUNTS", "1", 1);
  EXPECT_EQ(test_count("IMUCAL_CI_COUNT_TEST_N", 10, 40), 40);
  ::setenv("IMUCAL_CI_COUNT_TEST_N", "7", 1);
  EXPECT_EQ(test_count("IMUCAL_CI_COUNT_TEST_N", 10, 40), 7);
  ::setenv("IMUCAL_CI_COUNT_TEST_N", "zero", 1);  // not a positive count: ignored
  EXPECT_EQ(test_count("IMUCAL_CI_COUNT_TEST_N", 10, 40), 40);
  ::setenv("IMUCAL_WHOLE_COUNTS", "0", 1);
  EXPECT_EQ(test_count("IMUCAL_CI_COUNT_TEST_N", 10, 40), 10);
  ::unsetenv("IMUCAL_WHOLE_COUNTS");
  ::unsetenv("IMUCAL_CI_COUNT_TEST_N");
}

TEST(CiCount, TheBinomialTailMatchesClosedFormsAndATabulatedValue) {
  EXPECT_NEAR(binomial_tail_above(0, 40, 0.05), 1.0 - std::pow(0.95, 40), 1e-12);
  EXPECT_NEAR(binomial_tail_above(9, 10, 0.3), std::pow(0.3, 10), 1e-15);
  EXPECT_NEAR(binomial_tail_above(2, 10, 0.05), 0.01150, 1e-5);
  EXPECT_EQ(binomial_tail_above(10, 10, 0.5), 0.0);
  EXPECT_EQ(binomial_tail_above(-1, 10, 0.5), 1.0);
  EXPECT_EQ(binomial_tail_above(3, 10, 0.0), 0.0);
}

TEST(CiCount, AllowedEventsIsTheSmallestCountWithinTheLevel) {
  const int k = allowed_events(10, 0.05, 0.02);
  EXPECT_EQ(k, 2);  // P(X > 1) = 0.0861 > 0.02 >= P(X > 2) = 0.0115
  EXPECT_LE(binomial_tail_above(k, 10, 0.05), 0.02);
  EXPECT_GT(binomial_tail_above(k - 1, 10, 0.05), 0.02);
  EXPECT_EQ(allowed_events(10, 0.0, 0.01), 0);
}

}  // namespace
}  // namespace imucal::test_support
