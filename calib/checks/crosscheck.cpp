#include "calib/checks/crosscheck.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "calib/core/body_frame.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

namespace {

/// A number for an operator: about three significant digits without exponent clutter.
std::string human_number(double v) {
  char buf[64];
  const double a = std::abs(v);
  if (!std::isfinite(v) || a >= 1e6 || a < 1)
    std::snprintf(buf, sizeof buf, "%.3g", v);
  else if (a >= 100)
    std::snprintf(buf, sizeof buf, "%.0f", v);
  else
    std::snprintf(buf, sizeof buf, "%.1f", v);
  return buf;
}

std::string method_name(const CalibrationResult& r, const char* fallback) {
  return r.method.empty() ? std::string(fallback) : r.method;
}

void check_metric(const std::string& method, const char* term, const char* label, double value,
                  double limit, const char* unit, std::vector<CrossCheckFailure>& out) {
  if (std::isfinite(value) && value <= limit) return;
  out.push_back({term, method + ": " + label + " " + human_number(value) + " " + unit +
                           " > limit " + human_number(limit) + " " + unit});
}

}  // namespace

CrossCheckResult cross_check(const CalibrationResult& a_in, const EvaluationMetrics& ma,
                             const CalibrationResult& b_in, const EvaluationMetrics& mb,
                             const CrossCheckOptions& opt) {
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0.0))
      throw std::invalid_argument(std::string("cross_check: options.") + name + " = " +
                                  std::to_string(v) + " must be positive and finite");
  };
  positive(opt.k_sigma, "k_sigma");
  positive(opt.max_orientation_rmse_mdeg, "max_orientation_rmse_mdeg");
  positive(opt.max_accel_rmse_ug, "max_accel_rmse_ug");

  // Compare like with like: a housing-frame result is brought into the other's accel-symmetric
  // frame (the housing orientation is what only one of them knows).
  const bool same_frame = a_in.body_frame == b_in.body_frame;
  const CalibrationResult a = same_frame ? a_in : in_accel_symmetric_frame(a_in);
  const CalibrationResult b = same_frame ? b_in : in_accel_symmetric_frame(b_in);

  CrossCheckResult r;
  const ParamVector xa = a.params.to_vector(), xb = b.params.to_vector();
  const ParamVector sa = a.sigma.to_vector(), sb = b.sigma.to_vector();
  char k_buf[32];
  std::snprintf(k_buf, sizeof k_buf, "%g", opt.k_sigma);
  const std::string k_label = std::string(k_buf) + "σ";
  for (int i = 0; i < ParamSet::kSize; ++i) {
    const auto u = static_cast<size_t>(i);
    if (!a.observable[u] || !b.observable[u]) {
      r.skipped.push_back(param_info(i).name);
      continue;
    }
    const ParamInfo& info = param_info(i);
    const double diff = std::abs(xa(i) - xb(i));
    const double bound = opt.k_sigma * std::sqrt(sa(i) * sa(i) + sb(i) * sb(i));
    // Written so that NaN anywhere fails: a missing σ is not agreement.
    if (diff <= bound) continue;
    const double s = info.si_to_human;
    r.failures.push_back({info.name, info.name + ": |Δ| = " + human_number(diff * s) + " " +
                                         info.human_unit + " > " + k_label + " bound " +
                                         human_number(bound * s) + " " + info.human_unit});
  }
  const std::string na = method_name(a, "A"), nb = method_name(b, "B");
  // Metrics exist only where there is an attitude reference (not on land or at sea).
  for (const auto& [name, m] : {std::pair{na, &ma}, std::pair{nb, &mb}}) {
    if (!m->evaluated) continue;
    check_metric(name, "orientation_rmse_mdeg", "orientation RMSE", m->orientation_rmse_mdeg,
                 opt.max_orientation_rmse_mdeg, "mdeg", r.failures);
    check_metric(name, "accel_rmse_ug", "acceleration RMSE", m->accel_rmse_ug,
                 opt.max_accel_rmse_ug, "µg", r.failures);
  }
  r.pass = r.failures.empty();
  return r;
}

}  // namespace imucal::calib::checks
