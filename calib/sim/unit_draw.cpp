#include "calib/sim/unit_draw.hpp"

#include <random>

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

UnitModel draw_unit(Grade grade, uint64_t seed) {
  if (grade == Grade::kNavigation) return default_unit();
  const GradePrior p = grade_prior(grade);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto pick = [&](double envelope) { return envelope * u(rng); };
  UnitModel unit;
  unit.grade = grade;
  for (int i = 0; i < 3; ++i)
    unit.params.gyro_bias_radps(i) =
        (u(rng) > 0 ? 1.0 : -1.0) * (0.75 + 0.25 * u(rng)) * p.gyro_bias_radps;
  for (int i = 0; i < 3; ++i) unit.params.accel_bias_mps2(i) = pick(p.accel_bias_mps2);
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      unit.params.gyro_M(i, j) = pick(i == j ? 0.8 * p.scale : p.misalignment_rad);
      unit.params.accel_M(i, j) = pick(i == j ? p.scale / 3.0 : p.misalignment_rad);
    }
  unit.noise.arw_rad_per_sqrt_s = p.arw_rad_per_sqrt_s;
  unit.noise.vrw_mps_per_sqrt_s = p.vrw_mps_per_sqrt_s;
  return unit;
}

UnitModel draw_production_unit(Grade grade, uint64_t seed) {
  if (grade != Grade::kNavigation) return draw_unit(grade, seed);
  std::mt19937_64 rng(seed ^ 0x9e3779b97f4a7c15ULL);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  UnitModel unit = default_unit();
  ParamSet& p = unit.params;
  for (int i = 0; i < 3; ++i) {
    p.accel_bias_mps2(i) = 100.0 * kMicroG_mps2 * u(rng);
    p.gyro_bias_radps(i) = 0.02 * kDegPerHourToRadPerSec * u(rng);
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      p.accel_M(i, j) = 500e-6 * u(rng);
      p.gyro_M(i, j) = 500e-6 * u(rng);
    }
  p.table_misalignment_rad.setZero();
  return unit;
}

}  // namespace imucal::calib::sim
