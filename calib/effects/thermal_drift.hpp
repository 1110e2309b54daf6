#pragma once
// thermal_drift (ARCHITECTURE §7): the warm-up of the biases after power-on, b(t) = b + A
// exp(-t/τ), t from the run's first sample. A time trend, not locked to the orientation. Integrated
// exactly over the interval: ∫ A exp(-t/τ) dt = A τ (exp(-t0/τ) - exp(-t1/τ)).
#include <cmath>

#include "calib/effects/sensor_kinematics.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// ∫ exp(-t/τ) dt over the interval (s).
inline double thermal_weight_s(double tau_s, const SensorKinematics& s) {
  return tau_s * (std::exp(-s.t0_s / tau_s) - std::exp(-(s.t0_s + s.dt_s) / tau_s));
}

/// Perturbation of an increment by a warm-up of amplitude A (m/s² for dv, rad/s for dθ).
template <typename T>
Vec3<T> thermal_delta(const Vec3<T>& amplitude, double tau_s, const SensorKinematics& s) {
  return amplitude * T(thermal_weight_s(tau_s, s));
}

}  // namespace imucal::calib::effects
