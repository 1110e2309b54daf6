#include "calib/diagnosis/effect_magnitude.hpp"

#include <algorithm>
#include <cmath>

namespace imucal::calib::diagnosis {

NormEstimate debiased_norm(const Eigen::VectorXd& x, const Eigen::MatrixXd& S) {
  const double q = x.squaredNorm(), t = S.trace();
  const double m2 = std::max(0.0, q - t);
  // Var(|x|²) = 2 tr(Σ²) + 4 μᵀΣμ for x ~ N(μ, Σ), with μ estimated by the debiased direction; the
  // σ of the norm by the delta method, with the noise floor (2 tr Σ²)^(1/4) in the denominator so
  // that it stays finite (the norm's own spread) at m = 0.
  const double noise2 = 2.0 * (S * S).trace();
  const double mu_scale = q > 0.0 ? std::sqrt(m2 / q) : 0.0;
  const double var_q = noise2 + 4.0 * mu_scale * mu_scale * x.dot(S * x);
  NormEstimate e;
  e.value = std::sqrt(m2);
  e.sigma = std::sqrt(var_q) / (2.0 * std::sqrt(m2 + std::sqrt(noise2)));
  return e;
}

}  // namespace imucal::calib::diagnosis
