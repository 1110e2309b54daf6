#include "calib/core/rest_detector.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "calib/core/conventions.hpp"

namespace imucal::calib::core {

namespace {

void check(double v, const char* name) {
  if (!(std::isfinite(v) && v > 0.0))
    throw std::invalid_argument(std::string("rest detector: option ") + name +
                                " must be positive and finite, got " + std::to_string(v));
}

/// Prefix sums of the rotation increments, time and specific-force magnitude, so that every
/// window statistic costs O(1).
struct PrefixSums {
  std::vector<Eigen::Vector3d> dtheta;
  std::vector<double> dt, f, f2;
  explicit PrefixSums(const ImuSeries& imu)
      : dtheta(imu.size() + 1, Eigen::Vector3d::Zero()),
        dt(imu.size() + 1, 0.0),
        f(imu.size() + 1, 0.0),
        f2(imu.size() + 1, 0.0) {
    for (size_t k = 0; k < imu.size(); ++k) {
      const double fk = imu[k].dv_mps.norm() / imu[k].dt_s;
      dtheta[k + 1] = dtheta[k] + imu[k].dtheta_rad;
      dt[k + 1] = dt[k] + imu[k].dt_s;
      f[k + 1] = f[k] + fk;
      f2[k + 1] = f2[k] + fk * fk;
    }
  }
};

/// Quiet samples: the window around k has a small mean rate and a steady specific force.
std::vector<bool> quiet_samples(const ImuSeries& imu, const RestDetectorOptions& opt) {
  const size_t n = imu.size();
  const PrefixSums ps(imu);
  const double max_rate = opt.max_rate_degps * kDegToRad;
  std::vector<bool> quiet(n, false);
  size_t lo = 0, hi = 0;  // window [lo, hi) around k, by time
  for (size_t k = 0; k < n; ++k) {
    const double t = imu[k].t_s;
    while (lo < k && imu[lo].t_s < t - 0.5 * opt.window_s) ++lo;
    while (hi < n && imu[hi].t_s <= t + 0.5 * opt.window_s) ++hi;
    const double T = ps.dt[hi] - ps.dt[lo];
    const double m = static_cast<double>(hi - lo);
    if (!(T > 0.0) || m < 2) continue;
    const double rate = (ps.dtheta[hi] - ps.dtheta[lo]).norm() / T;
    const double fmean = (ps.f[hi] - ps.f[lo]) / m;
    const double fvar = std::max(0.0, (ps.f2[hi] - ps.f2[lo]) / m - fmean * fmean);
    quiet[k] = rate < max_rate && std::sqrt(fvar) < opt.max_force_std_mps2;
  }
  return quiet;
}

}  // namespace

std::vector<bool> detect_rest(const ImuSeries& imu, const RestDetectorOptions& opt) {
  check(opt.window_s, "window_s");
  check(opt.max_rate_degps, "max_rate_degps");
  check(opt.max_force_std_mps2, "max_force_std_mps2");
  check(opt.min_rest_s, "min_rest_s");
  if (!(std::isfinite(opt.edge_guard_s) && opt.edge_guard_s >= 0.0))
    throw std::invalid_argument("rest detector: option edge_guard_s must be >= 0 and finite");
  check_rest_detector_input(imu);
  return rests_from_quiet(imu, quiet_samples(imu, opt), opt.min_rest_s, opt.edge_guard_s);
}

void check_rest_detector_input(const ImuSeries& imu) {
  for (size_t k = 0; k < imu.size(); ++k)
    if (!(std::isfinite(imu[k].dt_s) && imu[k].dt_s > 0.0) || !imu[k].dtheta_rad.allFinite() ||
        !imu[k].dv_mps.allFinite())
      throw std::invalid_argument("rest detector: imu[" + std::to_string(k) +
                                  "] has a non-finite increment or a non-positive dt_s");
}

std::vector<bool> rests_from_quiet(const ImuSeries& imu, const std::vector<bool>& quiet,
                                   double min_rest_s, double edge_guard_s) {
  std::vector<bool> rest(imu.size(), false);
  size_t k = 0;
  while (k < imu.size()) {
    if (!quiet[k]) {
      ++k;
      continue;
    }
    size_t e = k;
    while (e < imu.size() && quiet[e]) ++e;
    // Span [k, e): keep it if long enough, trimmed by the guard at both ends.
    const double t0 = imu[k].t_s - imu[k].dt_s, t1 = imu[e - 1].t_s;
    if (t1 - t0 >= min_rest_s)
      for (size_t j = k; j < e; ++j)
        rest[j] = imu[j].t_s - imu[j].dt_s >= t0 + edge_guard_s && imu[j].t_s <= t1 - edge_guard_s;
    k = e;
  }
  return rest;
}

}  // namespace imucal::calib::core
