#pragma once
// NLSQ data reduction (paper §V, ARCHITECTURE §6): rest periods to mean specific forces (once per
// run) and rotations to a linearised gyro propagation (once per re-linearisation). Everything the
// Ceres residuals of calib/nlsq/nlsq_residuals.hpp need, and nothing per sample.
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/noise_model.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::calib::nlsq {
using namespace calib::core;

/// One rest period reduced to its mean raw specific force.
///
/// At rest the body turns at Earth rate ω = ω_ib_b w.r.t. inertial space and f_b is constant in
/// body axes, so each increment (conventions.hpp: body frame at the *start* of its interval) is
///   dv_k = f_b dt + ½ (ω × f_b) dt² + (1/6) ω × (ω × f_b) dt³.
/// Summed over the rest and divided by T = Σdt, with the error model (eq. 18) on top:
///   f_meas_b = (I + dM_a) (I + h1 [ω×] + h2 [ω×]²) f_b + b_a,  h1 = Σdt²/(2T), h2 = Σdt³/(6T).
/// The residuals invert exactly this relation (nlsq_rest_specific_force_b).
struct NlsqRestMean {
  size_t begin = 0, end = 0;  ///< sample range [begin, end) of the rest period
  size_t mid = 0;             ///< propagation to/from this rest starts at increment `mid`
  Eigen::Vector3d f_meas_b = Eigen::Vector3d::Zero();  ///< Σ dv~ / Σ dt, raw, m/s²
  double T_s = 0.0;
  double h1_s = 0.0;
  double h2_s2 = 0.0;
  Eigen::Matrix3d C_bn_ref = Eigen::Matrix3d::Identity();  ///< table attitude (without ς)
  double sigma_f_mps2 = 0.0;  ///< 1-σ per axis of f_meas_b from VRW and dv quantisation
};

/// Reduce each rest period. Noise: VRW gives σ² = VRW²/T per axis; an accumulating quantiser (the
/// simulator's and a real output register's) leaves one LSB residue at each end: 2·LSB²/12 / T²;
/// a per-sample rounding (a logger of counts) is white, LSB²/(12 dt) beside VRW² (noise_model.hpp).
std::vector<NlsqRestMean> nlsq_rest_means(const CalibrationInput& in,
                                          const std::vector<RestPeriod>& rests);

/// The gyro propagation over increments [begin, end) between two instants at which the table
/// attitude is known (both ends inside rest periods), linearised at θ0.
///
/// Strapdown attitude (calib/core/strapdown.hpp, eq. 5 integrated, at rest so ω_in = ω_ie):
///   Ĉ_bn(end) = E_n · C_bn(begin) · ΔC_b(θ),   E_n = exp(-[ω_ie_n T ×]),  ΔC_b = Π_k exp([dθ_k ×])
/// with dθ_k the increments compensated by θ (eq. 23 inverse). Perturbing the gyro parameters
/// θ_g = (b_g, dM_g row-major) by δθ_g perturbs each compensated increment by
///   δ_k = -(I + dM_g0)⁻¹ (δb_g dt + δdM_g dθ_k)
/// and, moving every perturbation to the end of the product,
///   ΔC_b(θ) ≈ ΔC_b(θ0) · exp([J_b δθ_g ×]),  J_b δθ_g = P_Nᵀ Σ_k P_k J_r(dθ_k) δ_k,
/// where P_k = Π_{j≤k} exp([dθ_j ×]) and J_r is the right Jacobian of exp. In the psi convention
/// (Ĉ = (I - [ψ×]) C) this is ψ = -Ĉ_bn(end) J_b δθ_g.
///
/// Three kinds of span are used (NlsqSpan): a rotation from the middle of rest A to the middle of
/// rest B (the paper's eq. 50 form, gravity only), a rotation from the last sample of rest A to
/// the first of rest B, and a whole rest R (A = B = R: the gyros must reproduce the Earth rate
/// while the table holds still). The last two tile the run without overlap.
struct NlsqRotation {
  size_t rest_a = 0, rest_b = 0;  ///< indices into the rest-mean vector (equal for a rest)
  size_t begin = 0, end = 0;      ///< increments [begin, end) propagated
  double T_s = 0.0;               ///< Σ dt over the propagation
  Eigen::Matrix3d E_n = Eigen::Matrix3d::Identity();    ///< exp(-[ω_ie_n T ×])
  Eigen::Matrix3d dC_b0 = Eigen::Matrix3d::Identity();  ///< ΔC_b(θ0)
  Eigen::Matrix<double, 3, 12> J_b = Eigen::Matrix<double, 3, 12>::Zero();
  Eigen::Matrix<double, 12, 1> theta_g0 = Eigen::Matrix<double, 12, 1>::Zero();
  /// 1-σ per axis of the propagated attitude from ARW + quantisation. Spans sharing an end point
  /// share that point's quantiser residue (correlation -½ of the LSB²/12 term, ~1e-7 of the ARW
  /// variance at datasheet values); this is neglected.
  double sigma_psi_rad = 0.0;
  double rotation_angle_rad = 0.0;  ///< angle between the table attitudes of A and B
};

enum class NlsqSpan {
  kMidRestToMidRest,    ///< increments [mid(A), mid(B)): eq. 50's rotation, rest halves included
  kRestEndToRestBegin,  ///< increments [end(A), begin(B)): the move alone (plus the rest guards)
  kWholeRest,           ///< increments [begin(R), end(R)) of one rest (rest_a = rest_b = R)
};

/// Build the propagation of the given span between rests A and B (for kWholeRest, rest_a must
/// equal rest_b) and linearise it at theta0 (only its gyro part is used).
NlsqRotation nlsq_linearise_rotation(const CalibrationInput& in,
                                     const std::vector<NlsqRestMean>& rests, size_t rest_a,
                                     size_t rest_b, const ParamSet& theta0,
                                     NlsqSpan span = NlsqSpan::kMidRestToMidRest);

/// ΔC_b(θ) propagated exactly (no linearisation) over increments [begin, end): used to check the
/// linearisation and by tests.
Eigen::Matrix3d nlsq_propagate_body(const ImuSeries& imu, size_t begin, size_t end,
                                    const ParamSet& theta);

}  // namespace imucal::calib::nlsq
