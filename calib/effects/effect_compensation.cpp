#include "calib/effects/effect_compensation.hpp"

#include <stdexcept>
#include <string>
#include <vector>

namespace imucal::calib::effects {
using namespace calib::core;

IncrementDelta sensor_effects_at(const ImuSeries& imu, size_t k, const ImuCompensator& comp,
                                 const Effects& fx, double t_first_s) {
  const ImuIncrement& x = imu[k];
  const double dt = x.dt_s;
  SensorKinematics kin;
  kin.f_b = comp.dv(x.dv_mps, dt) / dt;
  kin.w_b = comp.dtheta(x.dtheta_rad, dt) / dt;
  const ImuIncrement& prev = imu[k > 0 ? k - 1 : k];
  const ImuIncrement& next = imu[k + 1 < imu.size() ? k + 1 : k];
  const double span = 0.5 * (next.t_s - prev.t_s);
  if (span > 0.0)
    kin.wdot_b = (next.dtheta_rad / next.dt_s - prev.dtheta_rad / prev.dt_s) / (2.0 * span);
  kin.t0_s = x.t_s - dt - t_first_s;
  kin.dt_s = dt;
  return sensor_effects_delta(fx, kin, /*include_size_effect=*/true);
}

void check_removable(const Effects& fx) {
  for (const EffectInfo& e : effect_catalogue()) {
    if (e.kind == EffectKind::kSensor || !fx.active(e.id)) continue;
    throw std::invalid_argument(
        "effect " + e.name +
        (e.kind == EffectKind::kStochastic
             ? " is noise: it cannot be removed from the data (declare it in the noise model)"
             : " is not the unit's (the table's or the site's): it cannot be removed from the "
               "unit's data"));
  }
}

void remove_sensor_effects(ImuSeries& imu, const Effects& fx, const ParamSet& calibrated) {
  check_removable(fx);
  if (imu.empty()) return;
  const ImuCompensator comp(calibrated);
  const double t_first_s = imu.front().t_s - imu.front().dt_s;
  std::vector<IncrementDelta> d(imu.size());
  for (size_t k = 0; k < imu.size(); ++k) d[k] = sensor_effects_at(imu, k, comp, fx, t_first_s);
  for (size_t k = 0; k < imu.size(); ++k) {
    imu[k].dv_mps -= d[k].dv;
    imu[k].dtheta_rad -= d[k].dtheta;
  }
}

}  // namespace imucal::calib::effects
