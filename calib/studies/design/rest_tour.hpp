#pragma once
// A rotation sequence as the designer sees it: a tour of rest poses of the two-axis table, one
// single-axis rotation between consecutive poses, and each pose's share of the rest time. The
// table time is spent either turning (fixed by the angles, the rate and the acceleration) or at
// rest; the designer decides which poses to keep, how fast to turn and how to share the rest.
#include <string>
#include <vector>

#include "sequences/sequence.hpp"
#include "sequences/validator.hpp"

namespace imucal::calib::studies::design {

/// One rotation, taking the table from one rest pose to the next.
struct TourLeg {
  sequences::Axis axis = sequences::Axis::kOuter;
  double by_deg = 0.0;  ///< signed angle (sign = direction), never 0
};

struct RestTour {
  double outer0_deg = 0.0, inner0_deg = 0.0;  ///< the first pose
  std::vector<TourLeg> legs;                  ///< legs[i] turns pose i into pose i + 1
  /// Each pose's share of the rest time (legs.size() + 1 entries, > 0).
  std::vector<double> rest_weight;
  double rate_dps = 10.0, accel_dps2 = 10.0;  ///< of every rotation

  size_t poses() const { return legs.size() + 1; }
  /// (outer, inner) of pose i, in degrees (commanded encoder angles, no wrap-around).
  std::pair<double, double> pose_deg(size_t i) const;
  /// Time spent turning, s.
  double rotation_time_s() const;
};

/// The tour a sequence drives: its start pose and every rotation; the rests at one pose (a rest
/// after a rest) are summed, and each pose's weight is its rest time. Rotations of zero angle are
/// skipped. The rotations' rate and acceleration: the first rotation's.
RestTour tour_of(const sequences::Sequence& seq);

/// The sequence of `tour` lasting `total_s` with no rest under `min_rest_s`: the time not spent
/// turning is shared among the poses in proportion to their weights (a share under the minimum is
/// raised to it), rounded to 0.1 s. The tour of a sequence at its own time gives back its rests;
/// at another time, its rests scaled uniformly ("the obvious cut"). Throws std::invalid_argument
/// when the rotations and the minimum rests alone take longer than total_s.
sequences::Sequence sequence_of(const RestTour& tour, double total_s, double min_rest_s,
                                const std::string& name, const std::string& description);

/// The shortest sequence of `tour`: every rest at its minimum.
double minimum_time_s(const RestTour& tour, double min_rest_s);

/// A change of a tour and what it did, for the designer's report.
struct TourMove {
  RestTour tour;
  std::string what;
};

/// Every tour one rest pose shorter: a pose between two rotations about the same axis is dropped
/// and the two rotations become one (both go if they cancel, and the poses on either side, then
/// the same, become one); the first or the last pose is dropped with its rotation. Tours of one
/// rotation have no such neighbour.
std::vector<TourMove> tours_one_pose_shorter(const RestTour& tour);

/// Every tour with one rotation a full turn (360 deg) longer in its own sense, reaching the same
/// pose: more angle for the gyro scale factors and misalignments at the cost of table time. Only
/// on an axis without travel limits.
std::vector<TourMove> tours_one_turn_longer(const RestTour& tour,
                                            const sequences::TableLimits& limits);

/// Every tour with one rotation changed by a half turn (+180 or -180 deg, never to 0 nor beyond
/// one and a half turns): every later pose of that axis turned by 180 deg. On the inner axis this
/// points the horizontal body axes of the later poses the other way (north for south): the
/// heading balance that separates the accelerometer biases from the table's tilt. Only on an axis
/// without travel limits.
std::vector<TourMove> tours_half_turn_changed(const RestTour& tour,
                                              const sequences::TableLimits& limits);

/// The share of the rest moved: pose i's weight multiplied by `factor`.
RestTour with_rest_weight(const RestTour& tour, size_t pose, double factor);

}  // namespace imucal::calib::studies::design
