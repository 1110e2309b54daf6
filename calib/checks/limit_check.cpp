#include "calib/checks/limit_check.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace imucal::calib::checks {
using namespace calib::core;

namespace {

std::string number(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, std::abs(v) >= 100 || v == 0 ? "%.0f" : "%.3g", v);
  return buf;
}

void fail(const std::string& method, const std::string& term, const std::string& what,
          LimitCheckResult& out) {
  out.pass = false;
  out.failures.push_back({method, term, method + ": " + what});
}

void check_options(const LimitCheckOptions& o) {
  for (int g = 0; g < kNumParamGroups; ++g) {
    const double v = o.datasheet.of(static_cast<ParamGroup>(g));
    if (!(std::isfinite(v) && v > 0.0))
      throw std::invalid_argument("limit check: the datasheet limit of " +
                                  group_name(static_cast<ParamGroup>(g)) +
                                  " must be positive and finite");
  }
  if (!(o.max_orientation_rmse_mdeg > 0.0 && o.max_accel_rmse_ug > 0.0))
    throw std::invalid_argument("limit check: metric limits must be positive");
}

void check_metric(const std::string& method, const char* term, const char* label, double value,
                  double limit, const char* unit, LimitCheckResult& out) {
  if (std::isfinite(value) && value <= limit) return;
  fail(method, term,
       std::string(label) + " " + number(value) + " " + unit + " > limit " + number(limit) + " " +
           unit,
       out);
}

}  // namespace

double DatasheetLimits::of(ParamGroup g) const {
  switch (g) {
    case ParamGroup::kAccelBias:
      return accel_bias_mps2;
    case ParamGroup::kAccelScale:
      return accel_scale;
    case ParamGroup::kAccelMisalign:
      return accel_misalignment_rad;
    case ParamGroup::kGyroBias:
      return gyro_bias_radps;
    case ParamGroup::kGyroScale:
      return gyro_scale;
    case ParamGroup::kGyroMisalign:
      return gyro_misalignment_rad;
    case ParamGroup::kTableMisalign:
      return table_misalignment_rad;
  }
  return 0.0;
}

void check_limits(const CalibrationResult& r, const EvaluationMetrics& metrics, bool check_metrics,
                  const LimitCheckOptions& opt, LimitCheckResult& out) {
  check_options(opt);
  const std::string method = r.method.empty() ? "method" : r.method;
  if (!r.converged)
    fail(method, "converged", "did not converge in " + std::to_string(r.iterations) + " iterations",
         out);
  const ParamVector x = r.params.to_vector(), s = r.sigma.to_vector();
  for (int i = 0; i < ParamSet::kSize; ++i) {
    if (!r.observable[static_cast<size_t>(i)]) continue;
    const ParamInfo& info = param_info(i);
    if (!std::isfinite(x(i)) || !std::isfinite(s(i)) || s(i) < 0.0) {
      fail(method, info.name, info.name + " or its σ is not a finite number", out);
      continue;
    }
    const double limit = opt.datasheet.of(info.group);
    // Written so that NaN fails too.
    if (std::abs(x(i)) <= limit) continue;
    const double h = info.si_to_human;
    fail(method, info.name,
         info.name + " = " + number(x(i) * h) + " " + info.human_unit +
             " outside the datasheet envelope ±" + number(limit * h) + " " + info.human_unit,
         out);
  }
  if (check_metrics && metrics.evaluated) {
    check_metric(method, "orientation_rmse_mdeg", "orientation RMSE", metrics.orientation_rmse_mdeg,
                 opt.max_orientation_rmse_mdeg, "mdeg", out);
    check_metric(method, "accel_rmse_ug", "acceleration RMSE", metrics.accel_rmse_ug,
                 opt.max_accel_rmse_ug, "µg", out);
  }
}

DatasheetLimits limits_for_grade(const DatasheetLimits& limits, const UnitPrior& prior) {
  if (prior.plain_navigation()) return limits;
  const GradePrior p = prior.envelope();
  DatasheetLimits l = limits;
  l.accel_bias_mps2 = std::max(l.accel_bias_mps2, p.accel_bias_mps2);
  l.accel_scale = std::max(l.accel_scale, p.scale);
  l.accel_misalignment_rad = std::max(l.accel_misalignment_rad, p.misalignment_rad);
  l.gyro_bias_radps = std::max(l.gyro_bias_radps, p.gyro_bias_radps);
  l.gyro_scale = std::max(l.gyro_scale, p.scale);
  // A field result is in the accelerometer triad's own frame (calib/core/body_frame.hpp): the gyro
  // off-diagonals then carry the rotation between the triads as well, up to the accelerometers'
  // misalignment again.
  l.gyro_misalignment_rad = std::max(l.gyro_misalignment_rad, 2.0 * p.misalignment_rad);
  return l;
}

MetricLimits metric_limits_for_grade(const MetricLimits& limits, Grade grade) {
  if (grade == Grade::kNavigation) return limits;
  const GradePrior nav = grade_prior(Grade::kNavigation), g = grade_prior(grade);
  return {limits.orientation_rmse_mdeg * g.arw_rad_per_sqrt_s / nav.arw_rad_per_sqrt_s,
          limits.accel_rmse_ug * g.vrw_mps_per_sqrt_s / nav.vrw_mps_per_sqrt_s};
}

}  // namespace imucal::calib::checks
