// The separability judgement of the gap diagnosis (calib/diagnosis/gap_fit.hpp) on columns built
// with known correlations to the base: separable at or below the limit, a nuisance direction
// between the limit and fit_limit (fitted, never resolved), left out above it.
#include "calib/diagnosis/gap_fit.hpp"

#include <gtest/gtest.h>

#include <Eigen/QR>
#include <cmath>

using namespace imucal::calib;

using namespace imucal::calib::diagnosis;

namespace {

/// 200 rows, orthonormal columns: three base directions and three free ones.
Eigen::MatrixXd orthonormal_columns() {
  std::srand(7);
  const Eigen::MatrixXd R = Eigen::MatrixXd::Random(200, 6);
  return Eigen::HouseholderQR<Eigen::MatrixXd>(R).householderQ() *
         Eigen::MatrixXd::Identity(200, 6);
}

}  // namespace

TEST(Separability, DirectionsSortByTheirCorrelationWithTheBase) {
  const Eigen::MatrixXd Q = orthonormal_columns();
  const Eigen::MatrixXd Jb = Q.leftCols(3) * 3.0;
  // Candidate columns whose multiple correlations with the base are 0.2, 0.97 and 0.999.
  auto column = [&](double rho, int base, int free) {
    return Eigen::VectorXd(rho * Q.col(base) + std::sqrt(1.0 - rho * rho) * Q.col(free));
  };
  Eigen::MatrixXd Jc(200, 3);
  Jc << column(0.2, 0, 3), column(0.97, 1, 4), column(0.999, 2, 5);
  const Separability with = separability(Jb, Jc, 0.95, 1e-12, 0.995);
  EXPECT_EQ(with.basis.cols(), 1);
  EXPECT_EQ(with.nuisance.cols(), 1);
  EXPECT_NEAR(with.max_nuisance_correlation, 0.97, 1e-6);
  EXPECT_NEAR(with.max_correlation, 0.999, 1e-6);
  EXPECT_NEAR(with.min_correlation, 0.2, 1e-6);
  // The nuisance direction is the 0.97 column's (in the candidate's own parameters).
  const Eigen::VectorXd u = with.nuisance.col(0).normalized();
  EXPECT_NEAR(std::abs(u(1)), 1.0, 1e-6);
  // Without a fit limit no direction is a nuisance one: the 0.97 column stays out of the fit.
  const Separability without = separability(Jb, Jc, 0.95, 1e-12);
  EXPECT_EQ(without.basis.cols(), 1);
  EXPECT_EQ(without.nuisance.cols(), 0);
}
