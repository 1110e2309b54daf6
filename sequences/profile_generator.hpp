#pragma once
// Turns a Sequence into a MotionProfile: an initial rest, then per step either a rest segment or
// a single-axis trapezoidal rate profile (accelerate, cruise, decelerate; triangular when the
// angle is too short to reach the cruise rate). Angles inside the profile are in radians.
#include "sequences/motion_profile.hpp"
#include "sequences/sequence.hpp"

namespace imucal::sequences {

/// Timing of one rest-to-rest rotation of |angle| at cruise rate v and acceleration a.
struct RotationTiming {
  double accel_time_s = 0.0;   ///< duration of the acceleration phase (= deceleration phase)
  double cruise_time_s = 0.0;  ///< duration at constant rate (0 for a triangular profile)
  double peak_rate = 0.0;      ///< reached rate magnitude (= v unless triangular), units of v
  double total_s() const { return 2.0 * accel_time_s + cruise_time_s; }
};

/// Bang-coast-bang timing. Units are any consistent pair (deg, deg/s, deg/s^2 or rad, ...).
/// Requires rate > 0 and accel > 0; angle_abs >= 0.
RotationTiming rotation_timing(double angle_abs, double rate, double accel);

/// Angle change (deg) a rotation step commands when the axis is at current_deg.
double step_angle_change_deg(const Step& step, double current_deg);

/// Builds the profile. The final angle of every rotation equals the commanded angle (deg -> rad
/// of the running commanded value, no accumulated integration error); segments are contiguous.
/// A rotation of zero angle produces no segment. Throws SequenceError for steps the generator
/// cannot execute (non-positive or non-finite rate/accel/duration, non-finite angle); a Sequence
/// from parse_sequence_* never has those.
MotionProfile generate_profile(const Sequence& seq);

}  // namespace imucal::sequences
