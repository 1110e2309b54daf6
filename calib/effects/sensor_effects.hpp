#pragma once
// The sum of the sensor-level effects of calib/effects/catalogue.hpp on one sample interval: what
// the simulator adds to the ideal increments (after the error model of eq. 18/23) and what the
// diagnosis subtracts from the measured ones. The size effect is included at the interval's mean
// rate and acceleration (the simulator integrates it exactly by quadrature instead, see
// TruthKinematics::dv_lever, and passes include_size_effect = false).
#include "calib/effects/accel_asymmetry.hpp"
#include "calib/effects/accel_quadratic_k2.hpp"
#include "calib/effects/catalogue.hpp"
#include "calib/effects/gyro_accel_skew.hpp"
#include "calib/effects/gyro_g_sensitivity.hpp"
#include "calib/effects/sensor_kinematics.hpp"
#include "calib/effects/size_effect.hpp"
#include "calib/effects/thermal_drift.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

struct IncrementDelta {
  Vec3<double> dv = Vec3<double>::Zero();
  Vec3<double> dtheta = Vec3<double>::Zero();
};

inline IncrementDelta sensor_effects_delta(const Effects& fx, const SensorKinematics& s,
                                           bool include_size_effect) {
  IncrementDelta d;
  d.dv += k2_delta_dv<double>(fx.accel_k2_per_mps2, s);
  d.dv += asymmetry_delta_dv<double>(fx.accel_asym, s);
  d.dv += skew_delta_dv<double>(fx.gyro_accel_skew_s, s);
  if (include_size_effect) d.dv += size_effect_delta_dv<double>(fx.accel_lever_arm_m, s);
  d.dtheta += g_sensitivity_delta_dtheta<double>(fx.gyro_g_sens, s);
  if (!fx.thermal_accel_mps2.isZero() || !fx.thermal_gyro_radps.isZero()) {
    const double w = thermal_weight_s(fx.thermal_tau_s, s);
    d.dv += fx.thermal_accel_mps2 * w;
    d.dtheta += fx.thermal_gyro_radps * w;
  }
  return d;
}

}  // namespace imucal::calib::effects
