#pragma once
// The archive's human units of a random walk, in SI: one fixed expression each, which the writers
// invert exactly with human_for_si (run.toml's [noise] and [prior], unit files).
#include "calib/core/conventions.hpp"

namespace imucal::db::archive {

/// Angle random walk: deg/√h -> rad/√s.
inline double arw_to_si(double deg_per_sqrt_h) { return deg_per_sqrt_h * kDegToRad / 60.0; }
/// Velocity random walk: µg/√Hz -> (m/s)/√s.
inline double vrw_to_si(double ug_per_sqrt_hz) { return ug_per_sqrt_hz * kMicroG_mps2; }

}  // namespace imucal::db::archive
