#pragma once
// The legacy baseline (issue #9; the role of the paper's "proprietary" column, DESIGN §6): a
// textbook multi-position static + rate calibration that needs no attitude reference.
//  1. Rest periods (the reference's at_rest flags, which on land/sea come from the IMU data).
//  2. Accelerometers, multi-position static test: bias and a lower-triangular scale/
//     non-orthogonality matrix such that the compensated specific force has the magnitude of
//     local gravity in every rest position (Ceres, started from scratch: works on a unit far from
//     nominal).
//  3. Gyro bias, multi-position static: the mean rate of every rest equals bias + Earth rate,
//     whose vertical component is known from the compensated accelerometers and whose horizontal
//     direction (the unknown heading of each rest) is estimated with it.
//  4. Gyros, rate test: scale factors and misalignments such that integrating the compensated
//     gyros over every move turns the gravity direction of the rest before it into that of the
//     rest after it (Earth rate included).
// The result is an orthogonal body frame but not the housing orientation: it is reported in the
// accel-symmetric frame (calib/body_frame.hpp); ς is not estimated. σ from the least-squares
// covariance scaled by the residuals.
#include "calib/calibration_input.hpp"

namespace imucal::calib {

struct LegacyOptions {
  size_t min_rest_samples = 100;  ///< shorter rest runs are not used
  double trim_s = 1.0;            ///< dropped from both ends of every rest before averaging
};

/// Throws std::invalid_argument with the reason when the data cannot be calibrated (fewer than 6
/// usable rest positions, positions not spanning the sphere, non-finite input).
CalibrationResult calibrate_legacy(const CalibrationInput& in, const LegacyOptions& options = {});

}  // namespace imucal::calib
