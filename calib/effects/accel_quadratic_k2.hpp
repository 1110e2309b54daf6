#pragma once
// accel_quadratic_k2 (ARCHITECTURE §7): a second-order accelerometer scale term, δf_i = K2_i f_i².
// Even in f: at ±1 g it looks like a bias (K2 g² on both sides), only tilted positions (f_i² < g²)
// tell it apart. Parameters: K2 per axis, 1/(m/s²) (10 µg/g² = 1e-5/9.80665 per m/s²).
#include "calib/effects/sensor_kinematics.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// Increment perturbation δdv over one interval (evaluated at the interval-mean specific force).
template <typename T>
Vec3<T> k2_delta_dv(const Vec3<T>& k2_per_mps2, const SensorKinematics& s) {
  Vec3<T> d;
  for (int i = 0; i < 3; ++i) d(i) = k2_per_mps2(i) * T(s.f_b(i) * s.f_b(i) * s.dt_s);
  return d;
}

}  // namespace imucal::calib::effects
