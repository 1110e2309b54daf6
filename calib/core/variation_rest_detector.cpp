#include "calib/core/variation_rest_detector.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "calib/core/calibration_input.hpp"
#include "calib/core/rest_detector.hpp"
#include "calib/core/unusable_span.hpp"

namespace imucal::calib::core {

namespace {

void check_options(const VariationRestOptions& o) {
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0.0))
      throw std::invalid_argument(std::string("rest detector: option ") + name +
                                  " must be positive and finite, got " + std::to_string(v));
  };
  auto non_negative = [](double v, const char* name) {
    if (!(std::isfinite(v) && v >= 0.0))
      throw std::invalid_argument(std::string("rest detector: option ") + name +
                                  " must be >= 0 and finite, got " + std::to_string(v));
  };
  positive(o.window_s, "window_s");
  positive(o.variance_factor, "variance_factor");
  positive(o.min_rest_s, "min_rest_s");
  non_negative(o.edge_guard_s, "edge_guard_s");
  non_negative(o.still_rate_radps, "still_rate_radps");
  non_negative(o.still_force_mps2, "still_force_mps2");
  non_negative(o.rest_rate_spread_radps, "rest_rate_spread_radps");
  non_negative(o.tremor_rate_radps, "tremor_rate_radps");
  non_negative(o.tremor_force_noise_ratio, "tremor_force_noise_ratio");
  if (!(o.noise_quantile > 0.0 && o.noise_quantile < 1.0))
    throw std::invalid_argument("rest detector: option noise_quantile must be in (0, 1), got " +
                                std::to_string(o.noise_quantile));
}

/// Per-sample RMS deviation (per axis, about the window mean, N − 1 normalised) of a signal over
/// a centred window of `window_s`, by prefix sums of the signal and its square.
std::vector<double> windowed_rms_deviation(const ImuSeries& imu,
                                           const std::vector<Eigen::Vector3d>& x, double window_s) {
  const size_t n = x.size();
  std::vector<Eigen::Vector3d> s1(n + 1, Eigen::Vector3d::Zero()),
      s2(n + 1, Eigen::Vector3d::Zero());
  for (size_t k = 0; k < n; ++k) {
    s1[k + 1] = s1[k] + x[k];
    s2[k + 1] = s2[k] + x[k].cwiseProduct(x[k]);
  }
  std::vector<double> out(n, std::numeric_limits<double>::infinity());
  size_t lo = 0, hi = 0;
  for (size_t k = 0; k < n; ++k) {
    const double t = imu[k].t_s;
    while (lo < k && imu[lo].t_s < t - 0.5 * window_s) ++lo;
    while (hi < n && imu[hi].t_s <= t + 0.5 * window_s) ++hi;
    const double m = static_cast<double>(hi - lo);
    if (m < 3) continue;
    const Eigen::Vector3d mean = (s1[hi] - s1[lo]) / m;
    const Eigen::Vector3d var =
        ((s2[hi] - s2[lo]) - m * mean.cwiseProduct(mean)).cwiseMax(0.0) / (m - 1.0);
    out[k] = std::sqrt(var.sum() / 3.0);
  }
  return out;
}

/// Per-sample mean of a signal over a centred window of `window_s`.
std::vector<Eigen::Vector3d> windowed_mean(const ImuSeries& imu,
                                           const std::vector<Eigen::Vector3d>& x, double window_s) {
  const size_t n = x.size();
  std::vector<Eigen::Vector3d> s1(n + 1, Eigen::Vector3d::Zero()), out(n);
  for (size_t k = 0; k < n; ++k) s1[k + 1] = s1[k] + x[k];
  size_t lo = 0, hi = 0;
  for (size_t k = 0; k < n; ++k) {
    const double t = imu[k].t_s;
    while (lo < k && imu[lo].t_s < t - 0.5 * window_s) ++lo;
    while (hi < n && imu[hi].t_s <= t + 0.5 * window_s) ++hi;
    out[k] = (s1[hi] - s1[lo]) / static_cast<double>(hi - lo);
  }
  return out;
}

double quantile(std::vector<double> v, double q) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return 0.0;
  const size_t i = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(i), v.end());
  return v[i];
}

/// Quiet spans of at least min_rest_s, trimmed by the edge guard (rests_from_quiet).
std::vector<RestPeriod> quiet_spans(const ImuSeries& imu, const std::vector<bool>& quiet,
                                    const VariationRestOptions& o) {
  const std::vector<bool> rest = rests_from_quiet(imu, quiet, o.min_rest_s, o.edge_guard_s);
  std::vector<RestPeriod> spans;
  for (size_t k = 0; k < imu.size();) {
    if (!rest[k]) {
      ++k;
      continue;
    }
    RestPeriod s{k, k};
    while (s.end < imu.size() && rest[s.end]) ++s.end;
    spans.push_back(s);
    k = s.end;
  }
  return spans;
}

}  // namespace

VariationRestOptions variation_rest_options(Grade grade) {
  const GradePrior p = grade_prior(grade);
  VariationRestOptions o;
  o.still_rate_radps = p.still_rate_radps;
  o.still_force_mps2 = p.still_force_mps2;
  o.rest_rate_spread_radps = p.rest_rate_spread_radps;
  o.tremor_rate_radps = p.tremor_rate_radps;
  o.tremor_force_noise_ratio = p.tremor_force_noise_ratio;
  o.min_rest_s = p.min_rest_s;
  return o;
}

VariationRestResult detect_rest_by_variation(const ImuSeries& imu, const VariationRestOptions& o) {
  check_options(o);
  check_rest_detector_input(imu);
  VariationRestResult r;
  r.at_rest.assign(imu.size(), false);
  // Step 1: the variation of the raw rate and specific force. After dropped samples the increment
  // is its own sample's while dt_s spans the gap (find_time_gaps): over dt_s it would read a
  // fraction of the rate, and every window holding it would vary by tens of mg — a 400 Hz logger
  // that drops one sample in a hundred (x-io's NGIMU walk, docs/validation/corpus.md) had no rest
  // at all. Such a sample's rate is over one interval; the gap itself stays unusable.
  const double interval_s = median_interval_s(imu);
  std::vector<Eigen::Vector3d> w(imu.size()), f(imu.size());
  for (size_t k = 0; k < imu.size(); ++k) {
    const double own_s = imu[k].dt_s > 1.5 * interval_s ? interval_s : imu[k].dt_s;
    w[k] = imu[k].dtheta_rad / own_s;
    f[k] = imu[k].dv_mps / own_s;
  }
  const std::vector<double> dw = windowed_rms_deviation(imu, w, o.window_s);
  const std::vector<double> df = windowed_rms_deviation(imu, f, o.window_s);
  // Step 2: the unit's own noise from its quietest windows, and the quiet samples.
  r.rate_noise_radps = quantile(dw, o.noise_quantile);
  r.force_noise_mps2 = quantile(df, o.noise_quantile);
  const double root = std::sqrt(o.variance_factor);
  const double max_dw =
      std::max({root * r.rate_noise_radps, o.still_rate_radps, o.tremor_rate_radps});
  const double max_df =
      std::max(std::max(root, o.tremor_force_noise_ratio) * r.force_noise_mps2, o.still_force_mps2);
  std::vector<bool> quiet(imu.size());
  for (size_t k = 0; k < imu.size(); ++k) quiet[k] = dw[k] < max_dw && df[k] < max_df;
  // Step 3: long enough. Step 4: the common offset from these candidates; then every sample whose
  // window turns faster than the spread about it is moving (this also trims the gentle start and
  // end of a table's acceleration, which varies too little to be seen in step 2), and what stays
  // quiet is cut into rests again.
  const std::vector<RestPeriod> candidates = quiet_spans(imu, quiet, o);
  if (candidates.empty()) return r;
  r.gyro_offset_radps = median_rest_rate_radps(imu, candidates);
  // A hand holding a unit drifts as well as shakes: over a short window its mean rate reaches the
  // tremor rate (the MPU-6050 corpus recording: 1–2 °/s over 0.2 s with 0.3–0.6 °/s of variation
  // in six of its nine positions); a turn the hand makes is faster. Where there is no hand (the
  // tremor rate 0), the grade's spread.
  const double spread = std::max(o.rest_rate_spread_radps, o.tremor_rate_radps);
  if (spread > 0.0) {
    for (const auto& c : candidates)
      if ((mean_rate_radps(imu, c) - r.gyro_offset_radps).norm() > spread) ++r.rotations_rejected;
    const std::vector<Eigen::Vector3d> mean_w = windowed_mean(imu, w, o.window_s);
    for (size_t k = 0; k < imu.size(); ++k)
      quiet[k] = quiet[k] && (mean_w[k] - r.gyro_offset_radps).norm() <= spread;
  }
  for (const auto& s : quiet_spans(imu, quiet, o)) {
    ++r.rests;
    for (size_t j = s.begin; j < s.end; ++j) r.at_rest[j] = true;
  }
  return r;
}

}  // namespace imucal::calib::core
