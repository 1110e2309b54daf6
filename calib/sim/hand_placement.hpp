#pragma once
// A hand-placed multi-position run's motion (issue #21): what a field engineer does with a unit
// and no table — a rest of `first_rest_s`, then `positions` turns by hand (60 °/s, 200 °/s²)
// through varied attitudes, each followed by a rest drawn uniformly so that the field simulator's
// ±20 % duration jitter (FieldSimOptions::duration_jitter) leaves it within [min_rest_s,
// max_rest_s]. The public recording of tests/data/imu_tk_xsens was taken this way (a 50 s rest,
// 37 positions of 2–12 s). Not a table sequence: its rests are shorter and its turns faster than
// any table's limits allow, so it is built here, never validated as one.
#include <cstdint>

#include "sequences/motion_profile.hpp"

namespace imucal::calib::sim {

struct HandPlacementOptions {
  int positions = 38;
  double first_rest_s = 50.0;
  double min_rest_s = 3.0;
  double max_rest_s = 11.0;
  /// > 0: a slow constant-rate turn (10 °/s) about the vertical after the first rest, as a table's
  /// cruise would be (for the rest detector's tests).
  double cruise_deg = 0.0;
  /// The turns' rate and angular acceleration. A hand turns a unit at up to several hundred °/s
  /// (the corpus' MPU-6050 recording clips its ±250 °/s gyro in three moves).
  double move_rate_dps = 60.0;
  double move_accel_dps2 = 200.0;
};

/// Throws std::invalid_argument for a count < 1 or rests that are not 0 < min ≤ max.
sequences::MotionProfile hand_placed_profile(uint64_t seed, const HandPlacementOptions& o = {});

}  // namespace imucal::calib::sim
