// The per-IMU spread in kind (calib/studies/paper/paper_spread.hpp): rank correlations and
// coefficients of variation against values worked out by hand, and the paper's own figures against
// an independent computation (a Python script of issue #26's sixteenth session, quoted in the
// README: factory AINS orientation ranks against NLSQ / legacy / land / sea 0.94, 0.83, 0.14,
// 0.83; orientation against acceleration 0.03).
#include "calib/studies/paper/paper_spread.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace imucal::calib {
using namespace imucal::calib::studies::paper;
namespace {

TEST(PaperSpread, RankCorrelationByHand) {
  EXPECT_DOUBLE_EQ(rank_correlation({1, 2, 3, 4}, {10, 20, 30, 400}), 1.0);
  EXPECT_DOUBLE_EQ(rank_correlation({1, 2, 3, 4}, {4, 3, 2, 1}), -1.0);
  // Ties take their mean rank: ranks (1, 2.5, 2.5, 4) against (1, 2, 3, 4): 4.5 / sqrt(4.5 * 5).
  EXPECT_NEAR(rank_correlation({1, 2, 2, 3}, {5, 6, 7, 8}), 4.5 / std::sqrt(22.5), 1e-12);
  EXPECT_DOUBLE_EQ(rank_correlation({1, 1, 1}, {1, 2, 3}), 0.0);  // one side constant
  EXPECT_THROW(rank_correlation({1}, {1}), std::invalid_argument);
  EXPECT_THROW(rank_correlation({1, 2}, {1, 2, 3}), std::invalid_argument);
}

TEST(PaperSpread, CoefficientOfVariationAndRanksOfRows) {
  // Three units whose orientation doubles and whose acceleration falls across the units.
  std::vector<PaperRow> rows(3);
  for (size_t u = 0; u < 3; ++u)
    for (size_t c = 0; c < rows[u].size(); ++c)
      rows[u][c] = {static_cast<double>(u + 1), static_cast<double>(10 - u)};
  const PaperSpread s = paper_spread(rows);
  EXPECT_NEAR(s.cv[0][0], 0.5, 1e-12);        // sd 1 / mean 2
  EXPECT_NEAR(s.cv[0][1], 1.0 / 9.0, 1e-12);  // sd 1 / mean 9
  EXPECT_DOUBLE_EQ(s.rank_with_factory_ains[3][0], 1.0);
  EXPECT_DOUBLE_EQ(s.orientation_with_acceleration, -1.0);
  EXPECT_THROW(paper_spread({rows[0]}), std::invalid_argument);
}

TEST(PaperSpread, ThePapersOwnFiguresAsAnIndependentComputationHasThem) {
  const PaperSpread p = paper_spread(paper_published_rows());
  EXPECT_NEAR(p.rank_with_factory_ains[1][0], 0.94, 0.005);
  EXPECT_NEAR(p.rank_with_factory_ains[2][0], 0.83, 0.005);
  EXPECT_NEAR(p.rank_with_factory_ains[3][0], 0.14, 0.005);
  EXPECT_NEAR(p.rank_with_factory_ains[4][0], 0.83, 0.005);
  EXPECT_NEAR(p.orientation_with_acceleration, 0.03, 0.005);
}

}  // namespace
}  // namespace imucal::calib
