#pragma once
// size_effect (ARCHITECTURE §7): the three accelerometers sit at different points r_i of the unit
// (lever arms from the rotation centre, body axes, m). Accelerometer i senses component i of the
// kinematic acceleration at its own point, ([ω̇×] + [ω×]²) r_i, on top of the specific force at the
// centre. Only while the table turns: ∝ ω² in cruise, spikes ∝ ω̇ at the ramps.
#include <array>

#include "calib/effects/sensor_kinematics.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// Lever-arm specific force sensed by the accelerometers, body axes (component i from r_i).
template <typename T>
Vec3<T> size_effect_f_b(const std::array<Vec3<T>, 3>& r_m, const Vec3<double>& w_b,
                        const Vec3<double>& wdot_b) {
  Vec3<T> f;
  const Vec3<T> w = w_b.cast<T>(), wd = wdot_b.cast<T>();
  for (int i = 0; i < 3; ++i) {
    const Vec3<T>& r = r_m[static_cast<size_t>(i)];
    f(i) = (wd.cross(r) + w.cross(w.cross(r)))(i);
  }
  return f;
}

/// Increment perturbation over one interval at its mean rate and acceleration (the simulator
/// integrates the exact term by quadrature; this form is what the diagnosis subtracts).
template <typename T>
Vec3<T> size_effect_delta_dv(const std::array<Vec3<T>, 3>& r_m, const SensorKinematics& s) {
  return size_effect_f_b<T>(r_m, s.w_b, s.wdot_b) * T(s.dt_s);
}

}  // namespace imucal::calib::effects
