#pragma once
// NLSQ factory calibration (paper §V, eq. 48-50; DESIGN §6): batch nonlinear least squares with
// Ceres over the 27 parameters of ParamSet (accel bias, dM_a, gyro bias, dM_g, table
// misalignment ς).
//
// Data reduction (done once per run, or once per re-linearisation for the gyro part):
//  * every rest period is reduced to its mean raw specific force (calib/nlsq_preprocess.hpp);
//  * every rotation between consecutive rests A -> B is reduced to the product of the compensated
//    gyro increments from the middle of A to the middle of B at the current linearisation point
//    θ0, plus the 3x12 sensitivity of that product to (b_g, dM_g), accumulated along the rotation.
// The Ceres problem therefore has one small residual block per rest and per rotation
// (calib/nlsq_residuals.hpp), never one per sample. An outer loop re-linearises the gyro part
// until every parameter step is below convergence_sigma_ratio·σ.
//
// Residuals and weights: eq. 50 gives per rotation i the pair
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
#include <cstddef>

#include "calib/calibration_input.hpp"

namespace imucal::calib {

struct NlsqOptions {
  int max_outer_iterations = 10;          ///< re-linearisations of the gyro propagation
  double convergence_sigma_ratio = 0.01;  ///< stop when every |Δθ_i| < ratio·σ_i
  int ceres_max_iterations = 50;          ///< Levenberg-Marquardt iterations per linearisation
  size_t min_rest_samples = 100;          ///< shorter at_rest runs are not used as rest periods
  bool estimate_table_misalignment = true;  ///< false: ς held at zero (σ reported as 0)
};

/// Calibrate the 27 parameters from a factory run. Throws std::invalid_argument (message starting
/// "calibrate_nlsq:") when the input cannot be calibrated: sizes of imu/reference differ, non-finite
/// or non-positive values, fewer than 2 rest periods, no rotation between rests, a noise model
/// without ARW/VRW (needed to weight the residuals), or parameters not observable on the sequence.
CalibrationResult calibrate_nlsq(const CalibrationInput& in, const NlsqOptions& opt = {});

}  // namespace imucal::calib
