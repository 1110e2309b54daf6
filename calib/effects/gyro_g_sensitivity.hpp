#pragma once
// gyro_g_sensitivity (ARCHITECTURE §7): a gyro rate error proportional to the specific force, δω =
// G f (G 3x3, (rad/s)/(m/s²); row i = output axis i). The static gyro bias then changes with the
// orientation of the unit against gravity.
#include "calib/effects/sensor_kinematics.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

template <typename T>
Vec3<T> g_sensitivity_delta_dtheta(const Mat3<T>& G, const SensorKinematics& s) {
  return G * (s.f_b * s.dt_s).cast<T>();
}

}  // namespace imucal::calib::effects
