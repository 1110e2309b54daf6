#pragma once
// Linear-Gaussian fitting on whitened segment residuals (the diagnosis' workhorse, ARCHITECTURE
// §8): around the calibrated point the residuals are r(θ0 + δ) ≈ r0 + J δ, whitened so that under
// the model r0 ~ N(0, I) after the fit. Everything the diagnosis asks — the base refit, a
// candidate's joint refit, its likelihood ratio, the separability of its parameters from the base
// ones, the gap on held-out segments — is a least-squares question on (r0, J) restricted to some
// rows and columns.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "calib/core/unit_grade.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

struct GlsFit {
  Eigen::VectorXd x;    ///< the step δ minimising ||r0 + J δ||² on the rows used
  Eigen::MatrixXd cov;  ///< (JᵀJ)⁻¹ (whitened: the honest covariance of δ)
  double chi2 = 0.0;    ///< ||r0 + J δ||² on the rows used
  int dof = 0;          ///< rows used - columns
};

/// Least squares on the rows listed (all rows when `rows` is empty). Columns are scaled to unit
/// norm for the solve. Throws std::invalid_argument when the columns are rank deficient on those
/// rows.
GlsFit gls_fit(const Eigen::VectorXd& r0, const Eigen::MatrixXd& J,
               const std::vector<int>& rows = {});

/// The gap on held-out rows: for each fold, fit on the rows not in it and predict its rows.
struct HeldOutGap {
  double chi2 = 0.0;  ///< Σ over folds of ||r0_h + J_h δ_train||²
  double expected =
      0.0;  ///< its expectation if the model is right: Σ (n_h + tr(J_h Cov_train J_hᵀ))
  double ratio() const { return expected > 0.0 ? chi2 / expected : 0.0; }
};
/// folds[f] = the rows held out in fold f.
HeldOutGap held_out_gap(const Eigen::VectorXd& r0, const Eigen::MatrixXd& J,
                        const std::vector<std::vector<int>>& folds);

/// The same with correlated residuals (covariance S of the whitened residuals under a hypothesis,
/// e.g. a Gauss-Markov bias): each fold is fitted by generalised least squares on the others and
/// predicted by the conditional mean given them; χ² and its expectation use the conditional
/// covariance. With S = I this is held_out_gap.
HeldOutGap held_out_gap_correlated(const Eigen::VectorXd& r0, const Eigen::MatrixXd& J,
                                   const Eigen::MatrixXd& S,
                                   const std::vector<std::vector<int>>& folds);

/// Separability of a block of candidate columns Jc from base columns Jb (ARCHITECTURE §8: a
/// candidate correlating > 0.95 with the base parameters is not separable). Works in the
/// candidate's own parameter space: directions u with (Jc u) of negligible size have no signature
/// at all; of the others, the fraction of information left after the base parameters are
/// marginalised is λ(u) = 1 - ρ(u)², ρ the multiple correlation with the base parameters.
struct Separability {
  /// Candidate-parameter directions (columns) that are separable: fit the candidate in this basis.
  Eigen::MatrixXd basis;
  /// Directions that correlate above the limit but no more than `fit_limit` with the base: not
  /// separable, yet far from degenerate (variance inflation at most 1 / (1 - fit_limit²)). Fitted
  /// with the separable ones when the candidate is, so that its share of the gap is the
  /// candidate's and not a remainder another candidate takes; never reported as resolved.
  Eigen::MatrixXd nuisance;
  double max_nuisance_correlation = 0.0;
  /// Largest multiple correlation with the base over all directions that have a signature.
  double max_correlation = 0.0;
  /// Smallest such correlation (the best-separated direction); 1 if none has a signature.
  double min_correlation = 1.0;
  int no_signature = 0;  ///< directions with no signature on this sequence
  /// For the worst direction, the base columns that mimic it most (indices), strongest first.
  std::vector<int> aliases;
};
/// `signature_floor`: a direction whose ||Jc u||² stays below it (u in the columns' own units) has
/// no signature. `limit`: the correlation above which a direction is not separable; `fit_limit`
/// (> limit, else none): the one up to which such a direction is still a nuisance direction.
Separability separability(const Eigen::MatrixXd& Jb, const Eigen::MatrixXd& Jc, double limit,
                          double signature_floor, double fit_limit = 0.0);

/// The signature floor of separability() for candidate columns in units of the catalogue's typical
/// size: χ² 1e-4 (a 0.01 move of the whitened residuals) for an effect of the grade's typical size,
/// effect_scale times the catalogue's (calib/core/unit_grade.hpp).
inline double signature_floor(double effect_scale) { return 1e-4 / (effect_scale * effect_scale); }

/// How much larger than its catalogue typical size an effect may be on a unit of `grade`: the
/// grade's effect_scale (calib/core/unit_grade.hpp) for the unit's own effects (sensor and
/// stochastic); 1 for the table's and the site's, which do not follow the unit's grade, and for
/// a hand's tremor (rest_tremor), which is the hand's.
inline double effect_scale(EffectId id, Grade grade) {
  if (id == EffectId::kRestTremor) return 1.0;
  const EffectKind k = effect_info(id).kind;
  return k == EffectKind::kSensor || k == EffectKind::kStochastic ? grade_prior(grade).effect_scale
                                                                  : 1.0;
}

/// The largest plausible size of an effect on a unit of `grade`, in multiples of its catalogue
/// typical magnitude: `max_typical` × effect_scale, or the catalogue's physical bound for the grade
/// (EffectInfo::plausible_max) where that is lower.
inline double plausible_limit_typical(EffectId id, Grade grade, double max_typical) {
  const EffectInfo& e = effect_info(id);
  double limit = max_typical * effect_scale(id, grade);
  const double bound = e.plausible_max[static_cast<size_t>(grade)];
  const double t = e.magnitude(Eigen::Map<const Eigen::VectorXd>(
      e.typical.data(), static_cast<Eigen::Index>(e.typical.size())));
  if (std::isfinite(bound) && t > 0.0) limit = std::min(limit, bound / t);
  return limit;
}

/// A correlation as people read it in a note: three decimals ("0.977", not "0.977463").
std::string correlation_text(double r);

/// Largest canonical correlation between the parts of two column blocks that the base columns do
/// not explain (are two candidates telling the same story on this sequence?).
double canonical_correlation(const Eigen::MatrixXd& Jb, const Eigen::MatrixXd& A,
                             const Eigen::MatrixXd& B);

}  // namespace imucal::calib::diagnosis
