// The exact binomial interval the null-run false-alarm figures are quoted with (issue #22).
// Reference values are closed forms (k = 0 or n: 1 - (tail)^(1/n)) and the textbook interval for
// 5 of 100 (Clopper & Pearson 1934, as tabulated: 0.0164 - 0.1128).
#include "calib/core/binomial_interval.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace imucal::calib {
using namespace imucal::calib::core;
namespace {

TEST(BinomialInterval, NoEventsGivesTheClosedFormUpperBound) {
  const RateInterval r = clopper_pearson(0, 2000);
  EXPECT_EQ(r.rate, 0.0);
  EXPECT_EQ(r.lower, 0.0);
  EXPECT_NEAR(r.upper, 1.0 - std::pow(0.025, 1.0 / 2000.0), 1e-9);  // 0.184 %
}

TEST(BinomialInterval, AllEventsGivesTheClosedFormLowerBound) {
  const RateInterval r = clopper_pearson(50, 50);
  EXPECT_EQ(r.upper, 1.0);
  EXPECT_NEAR(r.lower, std::pow(0.025, 1.0 / 50.0), 1e-9);
}

TEST(BinomialInterval, FiveOfAHundredMatchesTheTabulatedInterval) {
  const RateInterval r = clopper_pearson(5, 100);
  EXPECT_NEAR(r.rate, 0.05, 1e-15);
  EXPECT_NEAR(r.lower, 0.0164, 1e-4);
  EXPECT_NEAR(r.upper, 0.1128, 1e-4);
}

TEST(BinomialInterval, ANarrowerLevelGivesANarrowerInterval) {
  const RateInterval a = clopper_pearson(3, 1000, 0.95), b = clopper_pearson(3, 1000, 0.68);
  EXPECT_GT(b.lower, a.lower);
  EXPECT_LT(b.upper, a.upper);
}

TEST(BinomialInterval, ImpossibleCountsAreRefused) {
  EXPECT_THROW(clopper_pearson(3, 2), std::invalid_argument);
  EXPECT_THROW(clopper_pearson(-1, 10), std::invalid_argument);
  EXPECT_THROW(clopper_pearson(0, 0), std::invalid_argument);
}

}  // namespace
}  // namespace imucal::calib
