#pragma once
// gyro_accel_skew (ARCHITECTURE §7): the accelerometers sample t_GA seconds after the gyros. A
// specific force fixed in the n-frame turns in body axes as ḟ_b = -ω × f_b, so the late sample
// reads f_b(t - t_GA) ≈ f_b + t_GA (ω × f_b). Only while rotating; the sign flips with the
// direction.
#include "calib/effects/sensor_kinematics.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

template <typename T>
Vec3<T> skew_delta_dv(const T& t_ga_s, const SensorKinematics& s) {
  return t_ga_s * (s.w_b.cross(s.f_b) * s.dt_s).cast<T>();
}

}  // namespace imucal::calib::effects
