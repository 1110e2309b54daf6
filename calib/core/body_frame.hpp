#pragma once
// The body frame of a calibration where the housing orientation is not observable (land, sea, the
// legacy method). Rotating the unit's body frame by R (b' = R b) changes the sensor models
//   f~ = (I + M_a) f_b + b_a = (I + M_a) Rᵀ f_b' + b_a,   likewise the gyros,
// and the attitude by the same R: without an attitude reference the data cannot tell the two
// apart, so three angles — a common rotation of both triads — are not observable. We fix them
// by a convention rather than by a prior: the body frame is the one in which I + M_a is symmetric
// (the polar decomposition I + M_a = S U, S symmetric positive definite, U a rotation; R = U).
// That frame is orthogonal, defined by the accelerometer triad alone and unique, and the
// constraint "M_a symmetric" is linear in M_a, so a filter can impose it exactly.
//
// A result in the housing frame (factory) is brought into this frame to compare it with a field
// or legacy result; the three angles of R are the housing orientation that only a factory run
// determines.
#include <Eigen/Core>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::calib::core {

struct BodyFrameChange {
  ParamSet params;    ///< in the accel-symmetric frame (biases and ς unchanged)
  Eigen::Matrix3d R;  ///< b' = R b: the housing-to-sensor-frame rotation
};

/// Express params (housing or any frame) in the accel-symmetric frame. Throws
/// std::invalid_argument when I + M_a is singular or not positive (a sign-flipped axis).
BodyFrameChange to_accel_symmetric_frame(const ParamSet& params);

/// The result in the accel-symmetric frame: params transformed, covariance by the Jacobian of the
/// transformation (numerical, exact to first order), sigma recomputed, body_frame set. A result
/// already in that frame is returned unchanged.
CalibrationResult in_accel_symmetric_frame(const CalibrationResult& result);

/// Rotation angle (rad) of the housing-to-sensor-frame rotation R of params, per axis (the
/// rotation vector of R): what a factory calibration knows and a field calibration cannot.
Eigen::Vector3d housing_rotation_rad(const ParamSet& params);

}  // namespace imucal::calib::core
