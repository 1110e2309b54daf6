// How precisely the paper's own six IMUs fix each column's mean
// (calib/studies/paper/paper_precision.hpp, issue #26). The figures on small sets are worked out by
// hand; the paper's are its published values (Tables I-IV), summed here without the code under
// test.
#include "calib/studies/paper/paper_precision.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace imucal::calib {
using namespace imucal::calib::studies::paper;
namespace {

TEST(MeanPrecision, StandardErrorLeaveOneOutAndTheExactBootstrapOnSmallSets) {
  // {1, 3}: mean 2, sd sqrt(2), s.e. 1; resample means 1, 2, 2, 3, two of four within ±25 %;
  // leaving out either moves the mean by 50 %.
  const MeanPrecision two = mean_precision({1.0, 3.0}, 0.25);
  EXPECT_DOUBLE_EQ(two.mean, 2.0);
  EXPECT_NEAR(two.standard_error, 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(two.resamples_within_bar, 0.5);
  EXPECT_FALSE(two.bar_held_by_own_units);

  // {1, 2, 6}: mean 3. A resample's sum is within ±25 % (6.75-11.25) only with exactly one 6 and
  // two of {1, 2} (sums 8-10): 3 places x 4 = 12 of 27. Leaving out the 6 moves the mean to 1.5.
  const MeanPrecision event = mean_precision({1.0, 2.0, 6.0}, 0.25);
  EXPECT_DOUBLE_EQ(event.resamples_within_bar, 12.0 / 27.0);
  EXPECT_EQ(event.most_influential, 2u);
  EXPECT_DOUBLE_EQ(event.mean_without_it, 1.5);
  EXPECT_FALSE(event.bar_held_by_own_units);
  // A wider bar (±100 %: sums 0-18) holds every resample and every leave-one-out mean but the
  // 6's (-50 %, within it).
  const MeanPrecision wide = mean_precision({1.0, 2.0, 6.0}, 1.0);
  EXPECT_DOUBLE_EQ(wide.resamples_within_bar, 1.0);
  EXPECT_TRUE(wide.bar_held_by_own_units);

  // Alike units: no scatter, every resample is the mean.
  const MeanPrecision alike = mean_precision({10.0, 10.0, 10.0, 10.0}, 0.01);
  EXPECT_DOUBLE_EQ(alike.standard_error, 0.0);
  EXPECT_DOUBLE_EQ(alike.resamples_within_bar, 1.0);
  EXPECT_TRUE(alike.bar_held_by_own_units);

  // Too many units to enumerate: the bootstrap is not computed, the rest is.
  const MeanPrecision many =
      mean_precision(std::vector<double>(kMaxExactBootstrapUnits + 1, 3.0), 0.25);
  EXPECT_LT(many.resamples_within_bar, 0.0);
  EXPECT_DOUBLE_EQ(many.mean, 3.0);
}

TEST(MeanPrecision, RefusesWhatHasNoPrecision) {
  EXPECT_THROW(mean_precision({1.0}, 0.25), std::invalid_argument);
  EXPECT_THROW(mean_precision({-1.0, 1.0}, 0.25), std::invalid_argument);
  EXPECT_THROW(mean_precision({1.0, 2.0}, 0.0), std::invalid_argument);
  EXPECT_THROW(mean_standard_error({}), std::invalid_argument);
}

TEST(MeanPrecision, DistanceOfAModelsMeanInCombinedStandardErrors) {
  const MeanPrecision paper = mean_precision({1.0, 3.0}, 0.25);  // mean 2, s.e. 1
  EXPECT_NEAR(mean_distance_in_standard_errors(2.0 + 5.0, std::sqrt(24.0), paper), 1.0, 1e-12);
  EXPECT_NEAR(mean_distance_in_standard_errors(0.0, 0.0, paper), -2.0, 1e-12);
}

// Issue #26 holds the model's mean of every column to within 25 % of the paper's. For nine of
// the ten means the paper's own IMUs hold that bar; for the legacy (proprietary) acceleration they
// do not: its mean is IMU 3's event (89.65 ug). The paper's other five IMUs average 29.11 ug, below
// the bar's edge (0.75 x 39.20 = 29.40): a model that reproduced those five exactly would miss it.
TEST(PaperPrecision, TheLegacyAccelerationBarIsNarrowerThanThePapersOwnImusHoldIt) {
  const std::vector<PaperRow> rows = paper_published_rows();
  ASSERT_EQ(rows.size(), 6u);
  const PaperPrecision p = paper_precision(rows, 0.25);
  const auto legacy = static_cast<size_t>(PaperColumn::kFactoryLegacy);

  const MeanPrecision& accel = p[legacy][1];
  const double published[6] = {21.9174, 29.7009, 89.6507, 28.2366, 31.6360, 34.0508};
  double sum = 0.0;
  for (double x : published) sum += x;
  const double others = (sum - published[2]) / 5.0;
  EXPECT_NEAR(others, 29.11, 0.01);
  EXPECT_LT(others, 0.75 * sum / 6.0) << "the other five IMUs leave the bar";
  EXPECT_EQ(accel.most_influential, 2u) << "IMU 3";
  EXPECT_NEAR(accel.mean_without_it, others, 1e-9);
  EXPECT_FALSE(accel.bar_held_by_own_units);
  EXPECT_GT(accel.standard_error / accel.mean, 0.25) << "its standard error exceeds the bar";
  EXPECT_LT(accel.resamples_within_bar, 0.70) << "a third of the paper's own resamples miss it";

  for (size_t c = 0; c < static_cast<size_t>(kNumPaperColumns); ++c)
    for (size_t m = 0; m < 2; ++m) {
      if (c == legacy && m == 1) continue;
      const MeanPrecision& q = p[c][m];
      EXPECT_TRUE(q.bar_held_by_own_units) << paper_column_name(static_cast<PaperColumn>(c)) << m;
      EXPECT_GT(q.resamples_within_bar, 0.93)
          << paper_column_name(static_cast<PaperColumn>(c)) << m;
      EXPECT_LT(q.standard_error / q.mean, 0.20)
          << paper_column_name(static_cast<PaperColumn>(c)) << m;
    }
}

}  // namespace
}  // namespace imucal::calib
