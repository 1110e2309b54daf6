#pragma once
// NLSQ factory calibration (paper §V, eq. 48-50; ARCHITECTURE §6): batch nonlinear least squares
// with Ceres over the 27 parameters of ParamSet (accel bias, dM_a, gyro bias, dM_g, table
// misalignment ς).
//
// Data reduction (done once per run, or once per re-linearisation for the gyro part):
//  * every rest period is reduced to its mean raw specific force (calib/nlsq/nlsq_preprocess.hpp);
//  * every gyro propagation span between two instants of known table attitude is reduced to the
//    product of its compensated gyro increments at the current linearisation point θ0, plus the
//    3x12 sensitivity of that product to (b_g, dM_g), accumulated along the span.
// The Ceres problem therefore has one small residual block per rest and per span
// (calib/nlsq/nlsq_residuals.hpp), never one per sample. An outer loop re-linearises the gyro part
// until every parameter step is below convergence_sigma_ratio·σ.
//
// Gravity-only form (NlsqOptions::use_table_heading = false), the paper's residuals: eq. 50 gives
// per rotation i the pair
//   a_A = C_bn_true(A) f(A) + g_n          (table attitude before the rotation)
//   b_B = Ĉ_bn(B) f(B) + g_n               (gyro-propagated attitude after it)
// (the paper writes "- g^n" with g as the accelerometer's reaction; in NED with g_n = (0,0,g) a
// body at rest has C_bn f = -g_n). Rest means are shared between consecutive rotations, so the
// stacked eq. 50 residuals are correlated. They are restructured, by an invertible linear map, into
// uncorrelated ones: a_R for every rest R (noise: the rest mean only) and
//   d_i = b_B - a_B = (Ĉ_bn(B) - C_bn_true(B)) f(B)
// for every rotation (noise: the angle random walk of the propagation interval only, which shows
// as tilt; d_i's vertical component is second order and is dropped). Each block is whitened by its
// own noise σ, so (JᵀJ)⁻¹ is the honest covariance. The last rest also gets its a_R (the table
// attitude is known there as at every rest; eq. 50 would use it if the sequence continued).
//
// Default: eq. 50 extended by the table heading (NlsqOptions::use_table_heading = true).
// Eq. 50 compares only the direction of gravity, so it keeps the tilt of each rotation's attitude
// error and throws away its heading, and it propagates from the middle of rest A to the middle of
// rest B, so each rotation's residual also carries the angle noise of two rest halves. The paper's
// NLSQ used gravity only; a factory with a precision table measures the full attitude at every rest
// sample, and the default uses it:
//   * a_R per rest, unchanged (accelerometers, ς);
//   * ψ_R = log(C_bn_true(R) Ĉ_bn(R)ᵀ) per rest, the gyros propagated over the whole rest (they
//     must reproduce the Earth rate while the table holds still);
//   * ψ_i = log(C_bn_true(B) Ĉ_bn(B)ᵀ) per rotation, propagated from the last sample of rest A to
//     the first of rest B, full 3-D (tilt as in d_i: the horizontal part of ψ_i times g is d_i;
//     plus heading). It replaces d_i; keeping both would count the same noise twice.
// The rest and rotation spans tile the run without overlap, so the three families have
// independent noise (VRW for a_R, ARW over disjoint intervals for ψ) and stay uncorrelated;
// each ψ is whitened by its isotropic angle noise (ARW²·T per axis plus quantisation). Measured on
// factory-std (20 seeds, tests/calib/factory_mc_slow_test.cpp), RMS error / CRLB of the gyro
// groups: bias 1.50 -> 1.07, scale 2.21 -> 0.98, misalignment 3.75 -> 0.81 (gravity only ->
// default); adding the heading alone with mid-rest spans gave only 1.34 / 2.39 / 2.40, the rest of
// the gain comes from not diluting each rotation with the rest halves' noise. Accelerometer
// precision is unchanged (its information comes from a_R in both forms); ς's heading component
// gains a little from the gyros' Earth-rate sensing at rest.
#include <cstddef>
#include <optional>

#include "calib/core/calibration_input.hpp"

namespace imucal::calib::nlsq {
using namespace calib::core;

struct NlsqOptions {
  int max_outer_iterations = 10;            ///< re-linearisations of the gyro propagation
  double convergence_sigma_ratio = 0.01;    ///< stop when every |Δθ_i| < ratio·σ_i
  int ceres_max_iterations = 50;            ///< Levenberg-Marquardt iterations per linearisation
  size_t min_rest_samples = 100;            ///< shorter at_rest runs are not used as rest periods
  bool estimate_table_misalignment = true;  ///< false: ς held at zero (σ reported as 0)
  /// true (default): eq. 50 extended by the table heading -- full 3-D attitude residuals ψ against
  /// the table per rotation (end of rest A to start of rest B) and per rest; false: the paper's
  /// gravity-only eq. 50 (2-D tilt d_i, mid-rest to mid-rest). See the notes above.
  bool use_table_heading = true;
  /// The first linearisation point (default: zero, a unit near nominal). Below navigation grade
  /// the pipeline starts from the legacy result: a MEMS unit's gyro offsets of degrees per second
  /// and scales 30 % off are beyond what the re-linearisations reach from zero.
  std::optional<ParamSet> start;
};

/// Calibrate the 27 parameters from a factory run. Throws std::invalid_argument (message starting
/// "NLSQ:") when the input cannot be calibrated: sizes of imu/reference differ,
/// non-finite or non-positive values, fewer than 2 rest periods, no rotation between rests, a noise
/// model without ARW/VRW (needed to weight the residuals), or parameters not observable on the
/// sequence.
CalibrationResult calibrate_nlsq(const CalibrationInput& in, const NlsqOptions& opt = {});

}  // namespace imucal::calib::nlsq
