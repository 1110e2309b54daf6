#pragma once
// The legacy baseline (issue #9; the role of the paper's "proprietary" column, ARCHITECTURE §6): a
// textbook multi-position static + rate calibration that needs no attitude reference.
//  1. Rest periods (the reference's at_rest flags, which on land/sea come from the IMU data); the
//     mean specific force and rate of each, trimmed at both ends.
//  2. Accelerometers, multi-position static test: bias and a lower-triangular scale/
//     non-orthogonality matrix T such that the compensated specific force has the magnitude of
//     local gravity in every rest position (Gauss–Newton from scratch: T = I, b = 0, so a unit far
//     from nominal is fine).
//  3. Gyro bias, multi-position static: the mean rate of every rest equals bias + Earth rate,
//     whose vertical component is known from the compensated accelerometers and whose horizontal
//     direction (the unknown heading of each rest) is estimated with it.
//  4. Rate test: integrating the compensated gyros over every move must turn the gravity
//     direction of the rest before it into that of the rest after it (Earth rate included). Fitted
//     jointly with step 2, because with a table's 90°/180° positions the magnitudes alone leave the
//     accelerometer non-orthogonality unobserved (it enters them squared). Steps 3 and 2+4
//     alternate until both converge (3 to 12 rounds).
// The result is an orthogonal body frame but not the housing orientation: it is reported in the
// accel-symmetric frame (calib/core/body_frame.hpp); ς is not estimated. σ from the least-squares
// covariance: residuals weighted by the unit's white noise over each rest's own length and each
// move's duration, each class (magnitudes, moves) scaled up to its own scatter where it exceeds
// the noise (variance components), the whole inflated by the reduced χ² when above 1.
// A move that holds a clipped or dropped sample (CalibrationInput::unusable) is left out of step 4
// and named in the result's warnings; fewer than 5 usable moves are refused (issue #48 item 3).
#include "calib/core/calibration_input.hpp"

namespace imucal::calib::legacy {
using namespace calib::core;

struct LegacyOptions {
  size_t min_rest_samples = 100;  ///< shorter rest runs are not used
  double trim_s = 1.0;            ///< dropped from both ends of every rest before averaging
};

/// Throws std::invalid_argument with the reason when the data cannot be calibrated (fewer than 9
/// usable rest positions, positions not spanning three dimensions, non-finite input, a fit that
/// does not converge).
CalibrationResult calibrate_legacy(const CalibrationInput& in, const LegacyOptions& options = {});

}  // namespace imucal::calib::legacy
