#pragma once
// The headline size of a multi-parameter effect (issue #19 item 6): the norm of its fitted
// (separable) parameters, debiased for the noise in them, with an honest σ. The plain norm of a
// k-parameter estimate carries its noise as size, E|x|² = |μ|² + tr Σ, and the delta-method σ along
// x ignores the other directions: a null factory-std run read a size effect of "900 ± 780 mm", and
// an isotropic 9-parameter null reads ≈ 3σ.
#include <Eigen/Dense>

namespace imucal::calib::diagnosis {

struct NormEstimate {
  double value = 0.0;  ///< sqrt(max(0, |x|² − tr Σ)): unbiased in the square, 0 when noise-level
  double sigma = 0.0;  ///< spread of value under Σ (never 0 while Σ is not)
};

/// x: the estimate in the magnitude's units (already scaled), S: its covariance (same units).
NormEstimate debiased_norm(const Eigen::VectorXd& x, const Eigen::MatrixXd& S);

}  // namespace imucal::calib::diagnosis
