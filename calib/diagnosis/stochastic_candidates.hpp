#pragma once
// The stochastic effects of the catalogue as diagnosis candidates (ARCHITECTURE §7-8). They
// have no deterministic signature to refit; each is estimated through the statistics it changes.
//
//  * quantisation: an accumulating output register rounds each increment with the remainder
//  carried,
//    so its error e_k - e_{k-1} has lag-1 autocovariance -LSB²/12, where white noise (ARW, VRW) has
//    none. Over the rest samples (each rest's mean removed) the pooled lag-1 autocovariance γ1 per
//    sensor estimates LSB² = -12 γ1 with σ(γ1) ≈ γ0/√N; the likelihood ratio is the squared z of
//    the departure from the declared LSB (one-sided). The held-out gap is that statistic on
//    held-out rests before and after the fitted LSB. A declared LSB rounded per sample (a logger
//    of counts, calib/core/noise_model.hpp) predicts γ1 = 0: it is white, like the noise.
//  * bias_instability: a Gauss-Markov bias (σ, τ) not in the noise model moves each segment's bias
//    away from the run's mean, correlated over |Δt| as exp(-|Δt|/τ). In the whitened segment
//    residuals this adds σ_a² G_a + σ_g² G_g to the unit covariance, G built from the bias columns
//    of each segment; σ_a, σ_g are found by restricted maximum likelihood (base parameters profiled
//    out) on a grid, τ on a grid; LR = 2 Δℓ (χ²(2), conservative at the boundary). Held-out: each
//    fold predicted by the conditional mean given the others.
#include <array>
#include <vector>

#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/gap_linearisation.hpp"
#include "calib/diagnosis/whiteness.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;

CandidateResult score_quantisation(const CalibrationInput& in, const std::vector<RestPeriod>& rests,
                                   int folds);

/// output_filter (calib/effects/output_filter.hpp): a first-order filter y_k = a y_{k-1} + (1-a)
/// x_k on the output makes the rest samples' lag-1 autocorrelation a > 0, where white noise with
/// the declared rounding gives -LSB²/12/γ0 <= 0 when carried, 0 when per sample. Per sensor the
/// pooled lag-1 sums (rest means removed) give z against white noise (the whiteness line's z);
/// LR = Σ z² over the sensors with z > 0 (one-sided: quantisation, the other lag-1 effect, has the
/// opposite sign). Its size is a per sensor (the mean-removal bias corrected for the filter),
/// σ(a) = √((1-a²)/pairs). The held-out gap: per fold of rests, z² of the held fold against white
/// noise (before) and against a fitted on the other folds (after), averaged over folds and sensors.
/// What it does not do: change the segment residuals. The filter's DC gain is 1, so a rest's mean
/// keeps the input's noise; the (1+a)/(1-a) inflation of a mean's variance is against the
/// per-sample scatter, and explains a segment excess only when the declared noise was read from
/// that scatter (the note states the factor; the gap model keeps the declared noise).
CandidateResult score_output_filter(const CalibrationInput& in,
                                    const std::vector<RestPeriod>& rests, int folds);

/// The output filter judged given a slow wandering of the bias (issue #49: a Gauss-Markov drift of
/// a few minutes' correlation time raises the rest samples' lag-1 autocorrelation too, and the
/// filter was named beside the bias instability on every independent simulator's drift run). A
/// drift correlates neighbouring samples alike — its autocovariance is flat over a few lags — where
/// a first-order filter's falls from lag 1 to lag 2 (γ1 - γ2 = γ0_f (a - a²) > 0). Per sensor the
/// pooled d = γ1 - γ2 + LSB²/12 (the declared carried rounding makes γ1 = -LSB²/12, γ2 = 0; a
/// per-sample one γ1 = 0, so d = γ1 - γ2; each rest's mean removed, its bias the same at both
/// lags) against σ(d) = γ0 √(1/pairs1 + 1/pairs2);
/// returns the one-sided p-value of Σ z² over the sensors with z > 0 (χ²(2)).
double output_filter_p_given_wandering(const CalibrationInput& in,
                                       const std::vector<RestPeriod>& rests);

/// An undeclared Gauss-Markov bias fitted by restricted maximum likelihood on the whitened
/// residuals with fixed-effect design J (the base columns, possibly with deterministic effects
/// appended).
struct GaussMarkovFit {
  double sigma_accel_mps2 = 0.0, sigma_gyro_radps = 0.0, tau_s = 0.0;
  /// The best σ's at each τ of the grid with their restricted log-likelihood (the profile over τ
  /// that set_gauss_markov_size reads the size's uncertainty from).
  struct AtTau {
    double tau_s = 0.0, sigma_accel_mps2 = 0.0, sigma_gyro_radps = 0.0, ell = 0.0;
  };
  std::vector<AtTau> profile;
  double lr = 0.0;    ///< 2 Δℓ against no Gauss-Markov bias, same design
  double chi2 = 0.0;  ///< GLS χ² under its covariance
  Eigen::MatrixXd S;  ///< covariance of the whitened residuals under it
};
GaussMarkovFit fit_gauss_markov(const GapLinearisation& lin, const Eigen::MatrixXd& J,
                                const std::vector<double>& tau_grid_s);

/// A Gauss-Markov bias fit `f` (on the design J: the base, or the base and a set of effects) as a
/// candidate's size: value_si (σ_gyro, σ_accel, τ), magnitude with its σ, params. The σ is the
/// larger of the likelihood's curvature along the fitted direction at the fitted τ and half the
/// distance to the smallest size any τ of the grid leaves within Δℓ = 2 of the best: σ and τ
/// trade off (a longer τ needs a larger σ for the same differences between segments), and on a
/// 2277 s run a drift of τ 500 s at 8× typical read 19.5 ± 1.2 × typical at τ 3000 s, so the
/// curvature alone made a navigation unit's drift "implausible" (issue #49).
void set_gauss_markov_size(CandidateResult& r, const GapLinearisation& lin,
                           const Eigen::MatrixXd& J, const GaussMarkovFit& f);

CandidateResult score_bias_instability(const GapLinearisation& lin,
                                       const std::vector<std::vector<int>>& folds,
                                       const std::vector<double>& tau_grid_s);

/// Expected likelihood-ratio non-centrality of the catalogue's typical pattern scaled by m (for the
/// detection thresholds of calib/diagnosis/effect_detectability.hpp), without data:
///  * quantisation: λ(m) = Σ_sensors z², z = ((m q_typ)² - q_declared²)/12 / σ(γ1);
///  * bias instability (small-signal): λ(m) = ½ m⁴ tr((M G M)²), M the projection off the base
///    columns, G = typ_a² G_a + typ_g² G_g at the typical τ.
double quantisation_noncentrality(const GapModel& model, double m);
///  * output filter: λ(m) = Σ_sensors a² × pairs, a = min(0.99, m a_typ) (E z = a √pairs).
double output_filter_noncentrality(const GapModel& model, double m);
double bias_instability_noncentrality(const GapLinearisation& lin, double m);

}  // namespace imucal::calib::diagnosis
