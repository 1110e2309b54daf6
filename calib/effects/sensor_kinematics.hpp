#pragma once
// What a sensor-level effect (ARCHITECTURE §7) needs to know about one sample interval: the unit's
// interval-mean specific force and angular rate (body axes, w.r.t. inertial space), its angular
// acceleration, and where the interval lies in the run. The simulator fills it from the true
// kinematics; the diagnosis fills it from the compensated measurements (the effects are small, so
// evaluating them at measured instead of true kinematics is exact to second order).
#include "calib/core/rotation.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

struct SensorKinematics {
  Vec3<double> f_b = Vec3<double>::Zero();     ///< interval-mean specific force, m/s²
  Vec3<double> w_b = Vec3<double>::Zero();     ///< interval-mean angular rate w.r.t. i, rad/s
  Vec3<double> wdot_b = Vec3<double>::Zero();  ///< angular acceleration, rad/s²
  double t0_s = 0.0;                           ///< interval start, s from the run's first sample
  double dt_s = 0.0;                           ///< interval length, s
};

}  // namespace imucal::calib::effects
