#pragma once
// A unit's stochastic model: what the truth simulator draws its noise from and what the
// estimators weight their observations with (a datasheet or the unit file, ARCHITECTURE §3). Shared
// by both sides, so it lives with the conventions rather than in either.
#include "calib/core/conventions.hpp"

namespace imucal::calib::core {

/// Stochastic model of a unit (SI units; see unit-file parsing for human units).
struct NoiseModel {
  double arw_rad_per_sqrt_s = 0.0015 * kDegToRad / 60.0;  ///< angle random walk (0.0015 deg/√h)
  double vrw_mps_per_sqrt_s = 10.0 * kMicroG_mps2;        ///< velocity random walk (10 µg/√Hz)
  double gyro_bias_instability_radps = 0.0;               ///< Gauss-Markov σ
  double gyro_bias_tau_s = 1000.0;
  double accel_bias_instability_mps2 = 0.0;
  double accel_bias_tau_s = 1000.0;
  double dtheta_lsb_rad = 1e-9;  ///< quantisation of the output (0 = off)
  double dv_lsb_mps = 1e-7;
};

}  // namespace imucal::calib::core
