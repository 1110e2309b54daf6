#include "calib/core/calibration_input.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "calib/core/rest_detector.hpp"
#include "calib/core/variation_rest_detector.hpp"

namespace imucal::calib::core {

const char* setting_name(Setting s) {
  switch (s) {
    case Setting::kFactory:
      return "factory";
    case Setting::kLand:
      return "land";
    case Setting::kSea:
      return "sea";
  }
  return "factory";
}

std::optional<Setting> parse_setting(const std::string& name) {
  for (Setting s : {Setting::kFactory, Setting::kLand, Setting::kSea})
    if (name == setting_name(s)) return s;
  return std::nullopt;
}

std::vector<RestPeriod> find_rest_periods(const CalibrationInput& in, size_t min_samples) {
  std::vector<RestPeriod> out;
  const size_t n = in.reference.size();
  size_t k = 0;
  while (k < n) {
    if (!in.reference[k].at_rest) {
      ++k;
      continue;
    }
    size_t e = k;
    while (e < n && in.reference[e].at_rest) ++e;
    if (e - k >= min_samples) out.push_back({k, e});
    k = e;
  }
  return out;
}

std::vector<TrimmedRest> trimmed_rests(const CalibrationInput& in, size_t min_samples,
                                       double trim_s) {
  std::vector<TrimmedRest> out;
  for (const RestPeriod& rp : find_rest_periods(in, min_samples)) {
    const double length_s = in.imu[rp.end - 1].t_s - in.imu[rp.begin].t_s;
    const double trim = std::min(trim_s, 0.25 * length_s);
    const double t0 = in.imu[rp.begin].t_s + trim, t1 = in.imu[rp.end - 1].t_s - trim;
    TrimmedRest r;
    r.begin = rp.begin;
    while (r.begin < rp.end && in.imu[r.begin].t_s < t0) ++r.begin;
    r.end = r.begin;
    while (r.end < rp.end && in.imu[r.end].t_s <= t1) ++r.end;
    if (r.end - r.begin < min_samples / 2) continue;
    r.mid = (r.begin + r.end) / 2;
    out.push_back(r);
  }
  return out;
}

Eigen::Vector3d mean_rate_radps(const ImuSeries& imu, const RestPeriod& rest) {
  Eigen::Vector3d dtheta = Eigen::Vector3d::Zero();
  double T = 0.0;
  for (size_t k = rest.begin; k < rest.end; ++k) {
    dtheta += imu[k].dtheta_rad;
    T += imu[k].dt_s;
  }
  return dtheta / T;
}

Eigen::Vector3d median_rest_rate_radps(const ImuSeries& imu, const std::vector<RestPeriod>& rests) {
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  if (rests.empty()) return m;
  std::vector<Eigen::Vector3d> rates;
  for (const auto& r : rests) rates.push_back(mean_rate_radps(imu, r));
  for (int ax = 0; ax < 3; ++ax) {
    std::vector<double> v;
    for (const auto& w : rates) v.push_back(w(ax));
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    m(ax) = v[v.size() / 2];
  }
  return m;
}

ParamSet sigma_from_covariance(const ParamCovariance& cov) {
  ParamVector s = cov.diagonal().cwiseMax(0.0).cwiseSqrt();
  return ParamSet::from_vector(s);
}

CalibrationInput input_from_field_data(Setting setting, const ImuSeries& imu,
                                       const std::vector<GnssFix>& gnss, const Site& site,
                                       const NoiseModel& noise, Grade grade, double min_rest_s) {
  CalibrationInput in;
  in.setting = setting;
  in.site = site;
  in.imu = imu;
  in.gnss = gnss;
  in.noise = noise;
  in.grade = grade;
  std::vector<bool> rest;
  if (grade == Grade::kNavigation) {
    RestDetectorOptions o;
    if (min_rest_s > 0.0) o.min_rest_s = min_rest_s;
    rest = detect_rest(imu, o);
  } else {
    VariationRestOptions o = variation_rest_options(grade);
    if (min_rest_s > 0.0) o.min_rest_s = min_rest_s;
    rest = detect_rest_by_variation(imu, o).at_rest;
  }
  in.reference.resize(imu.size());
  for (size_t k = 0; k < imu.size(); ++k) {
    in.reference[k].t_s = imu[k].t_s;
    in.reference[k].at_rest = rest[k];
  }
  in.unusable = find_unusable_spans(imu);
  for (const UnusableSpan& s : in.unusable)
    for (size_t k = s.begin; k < s.end; ++k) in.reference[k].at_rest = false;
  return in;
}

void check_input_samples(const CalibrationInput& in, const std::string& who) {
  // Messages are built only on failure: this loop runs over every sample of an hour-long run.
  auto fail = [&who](const std::string& what) { throw std::invalid_argument(who + what); };
  auto at = [](const char* field, size_t k) {
    return std::string(field) + "[" + std::to_string(k) + "]";
  };
  const size_t n = in.imu.size();
  if (n == 0) fail("input has no IMU samples");
  if (in.reference.size() != n)
    fail("imu has " + std::to_string(n) + " samples but reference has " +
         std::to_string(in.reference.size()) + " (must be equal, same time axis)");
  for (size_t k = 0; k < n; ++k) {
    const ImuIncrement& s = in.imu[k];
    if (!std::isfinite(s.t_s)) fail(at("imu", k) + ".t_s is not finite");
    if (!(std::isfinite(s.dt_s) && s.dt_s > 0.0))
      fail(at("imu", k) + ".dt_s must be finite and > 0");
    if (!s.dtheta_rad.allFinite()) fail(at("imu", k) + ".dtheta_rad is not finite");
    if (!s.dv_mps.allFinite()) fail(at("imu", k) + ".dv_mps is not finite");
    if (k > 0 && !(s.t_s > in.imu[k - 1].t_s)) fail(at("imu", k) + ".t_s is not increasing");
    const ReferenceSample& r = in.reference[k];
    if (!(std::abs(r.t_s - s.t_s) <= 0.5 * s.dt_s))
      fail(at("reference", k) + ".t_s differs from imu[k].t_s by more than half a sample");
    if (!in.has_reference_attitude()) continue;
    if (!r.C_bn_ref.allFinite()) fail(at("reference", k) + ".C_bn_ref is not finite");
    if ((r.C_bn_ref.transpose() * r.C_bn_ref - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() >
            1e-6 ||
        r.C_bn_ref.determinant() < 0.0)
      fail(at("reference", k) + ".C_bn_ref is not a rotation matrix");
  }
}

}  // namespace imucal::calib::core
