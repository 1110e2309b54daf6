#include "calib/core/unit_grade.hpp"

#include <limits>

#include "calib/core/conventions.hpp"

namespace imucal::calib::core {

const char* grade_name(Grade g) {
  switch (g) {
    case Grade::kNavigation:
      return "navigation";
    case Grade::kTactical:
      return "tactical";
    case Grade::kMems:
      return "mems";
  }
  return "navigation";
}

std::optional<Grade> parse_grade(const std::string& name) {
  for (Grade g : {Grade::kNavigation, Grade::kTactical, Grade::kMems})
    if (name == grade_name(g)) return g;
  return std::nullopt;
}

namespace {

/// Tactical and MEMS gyros cannot find north: the first still position of any length serves,
/// wherever it begins, levelling needs about a second, and a hand's tremor is still rest.
void levels_only(GradePrior& p) {
  p.first_rest_min_s = 0.0;
  p.first_rest_latest_start_s = std::numeric_limits<double>::infinity();
  p.alignment_min_window_s = 1.0;
  p.tremor_rate_radps = 2.0 * kDegToRad;
  p.tremor_force_noise_ratio = 2.5;
  p.min_rest_s = 1.5;
}

}  // namespace

GradePrior grade_prior(Grade g) {
  constexpr double kDegPerHour = kDegToRad / 3600.0;
  constexpr double kDegPerSqrtHour = kDegToRad / 60.0;
  constexpr double kMilliG = 1e3 * kMicroG_mps2;
  GradePrior p;
  switch (g) {
    case Grade::kNavigation:
      p.gyro_bias_radps = 0.05 * kDegPerHour;
      p.accel_bias_mps2 = 1.0 * kMilliG;
      p.scale = 1e-3;
      p.misalignment_rad = 1e-3;
      p.arw_rad_per_sqrt_s = 0.005 * kDegPerSqrtHour;
      p.vrw_mps_per_sqrt_s = 50.0 * kMicroG_mps2;
      p.still_rate_radps = 0.05 * kDegToRad;
      p.still_force_mps2 = 0.005;
      p.rest_rate_spread_radps = 0.02 * kDegToRad;
      p.first_rest_min_s = 20.0;
      p.first_rest_latest_start_s = 10.0;
      p.alignment_min_window_s = 10.0;
      break;
    case Grade::kTactical:
      p.gyro_bias_radps = 10.0 * kDegPerHour;
      p.accel_bias_mps2 = 5.0 * kMilliG;
      p.scale = 1e-2;
      p.misalignment_rad = 5e-3;
      p.arw_rad_per_sqrt_s = 0.2 * kDegPerSqrtHour;
      p.vrw_mps_per_sqrt_s = 100.0 * kMicroG_mps2;
      p.still_rate_radps = 0.05 * kDegToRad;
      p.still_force_mps2 = 0.005;
      p.rest_rate_spread_radps = 0.1 * kDegToRad;
      p.effect_scale = 100.0;
      levels_only(p);
      break;
    case Grade::kMems:
      p.gyro_bias_radps = 5.0 * kDegToRad;
      p.accel_bias_mps2 = 200.0 * kMilliG;
      p.scale = 0.30;
      p.misalignment_rad = 50e-3;
      p.arw_rad_per_sqrt_s = 1.0 * kDegPerSqrtHour;
      p.vrw_mps_per_sqrt_s = 300.0 * kMicroG_mps2;
      p.still_rate_radps = 0.1 * kDegToRad;
      p.still_force_mps2 = 0.01;
      p.rest_rate_spread_radps = 0.5 * kDegToRad;
      p.effect_scale = 1e4;
      levels_only(p);
      break;
  }
  return p;
}

GradePrior UnitPrior::envelope() const {
  GradePrior p = grade_prior(grade);
  if (overrides.gyro_bias_radps) p.gyro_bias_radps = *overrides.gyro_bias_radps;
  if (overrides.accel_bias_mps2) p.accel_bias_mps2 = *overrides.accel_bias_mps2;
  if (overrides.scale) p.scale = *overrides.scale;
  if (overrides.misalignment_rad) p.misalignment_rad = *overrides.misalignment_rad;
  return p;
}

EnvelopeRange envelope_range() {
  return {100.0 * kDegToRad, 2.0 * kStandardGravity_mps2, 0.5, 0.2};
}

}  // namespace imucal::calib::core
