#pragma once
// accel_asymmetry (ARCHITECTURE §7): scale factor different for positive and negative input,
// δf_i = Kap_i |f_i| (dimensionless). Like K2 it aliases into bias at ±1 g; at tilts it grows as
// |cos| rather than cos².
#include <cmath>

#include "calib/effects/sensor_kinematics.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

template <typename T>
Vec3<T> asymmetry_delta_dv(const Vec3<T>& kap, const SensorKinematics& s) {
  Vec3<T> d;
  for (int i = 0; i < 3; ++i) d(i) = kap(i) * T(std::abs(s.f_b(i)) * s.dt_s);
  return d;
}

}  // namespace imucal::calib::effects
