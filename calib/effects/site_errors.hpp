#pragma once
// gravity_error and latitude_error (ARCHITECTURE §7): the station's Earth model is wrong. The true
// site is the configured one with latitude + dlat and gravity + dg (the configured surveyed
// gravity, or normal gravity at the true latitude when none is configured). A gravity error looks
// like a common accelerometer scale factor on every axis; a latitude error splits the Earth rate
// wrongly between north and down, an orientation-dependent gyro residual.
#include "calib/core/earth.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// The site as it really is, given the configured one and the two errors.
inline Site true_site(const Site& configured, double gravity_error_mps2,
                      double latitude_error_rad) {
  Site s = configured;
  s.lat_rad = configured.lat_rad + latitude_error_rad;
  const double g = configured.gravity_mps2 ? *configured.gravity_mps2
                                           : EarthModel::normal_gravity_mps2(s.lat_rad, s.height_m);
  if (configured.gravity_mps2 || gravity_error_mps2 != 0.0) s.gravity_mps2 = g + gravity_error_mps2;
  return s;
}

}  // namespace imucal::calib::effects
