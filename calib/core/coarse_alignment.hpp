#pragma once
// Initial attitude from the IMU data alone (issue #9: land and sea have no attitude reference):
// levelling and gyrocompassing on the first rest period, from scratch, in the inertial frame so
// that a rocking platform does not disturb it (the idea of inertial-frame / optimisation-based
// alignment, e.g. Wu & Pan 2013; Groves §5.6).
//
// Frames: b0 = the body at the window start, i0 = the navigation frame at that instant, frozen in
// inertial space. Over the window the gyros give C_b0_b(t) (rocking included, no Earth model
// needed), so the specific force integrated in b0,  u = Σ C_b0_b dv,  equals C_b0_i0 W with
// W = ∫ exp(τ [ω_ie_n ×]) f_n dτ,  f_n = (0, 0, -g),  known analytically. Gravity turning with
// the Earth in i0 is what carries heading: TRIAD with the whole-window sums as the primary pair
// (tilt) and the difference of the second and first halves as the secondary pair (heading).
// Accuracy on a still unit: tilt ≈ accelerometer bias / g, heading ≈ east gyro bias /
// (Ω cos φ) — the gyrocompass limits; a DP vessel's velocity change over the window adds
// Δv / (g Ω cos φ T² / 4) to the heading. The AINS refines both from there.
#include <Eigen/Core>

#include "calib/core/earth.hpp"
#include "calib/core/imu_increment.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::calib::core {

struct CoarseAlignment {
  Eigen::Matrix3d C_bn = Eigen::Matrix3d::Identity();  ///< at imu[begin].t_s
  double window_s = 0.0;
  /// Predicted 1-σ heading error from the accelerometer noise alone (rad): a lower bound.
  double heading_noise_sigma_rad = 0.0;
};

/// Align on samples (begin, end) of imu (the attitude refers to the end of sample `begin`).
/// Increments are compensated with `nominal`. vrw_mps_per_sqrt_s feeds heading_noise_sigma_rad.
/// Throws std::invalid_argument for a window shorter than min_window_s (10 s: gyrocompassing; a
/// grade that cannot find north levels in about a second, GradePrior::alignment_min_window_s), a
/// latitude within 1° of a pole (no horizontal Earth rate) or degenerate vectors (the unit was not
/// at rest).
CoarseAlignment coarse_align(const ImuSeries& imu, size_t begin, size_t end, const Site& site,
                             const ParamSet& nominal, double vrw_mps_per_sqrt_s,
                             double min_window_s = 10.0);

}  // namespace imucal::calib::core
