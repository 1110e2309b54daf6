#include "calib/core/calibration_input.hpp"

#include "calib/core/rest_detector.hpp"

namespace imucal::calib {

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

ParamSet sigma_from_covariance(const ParamCovariance& cov) {
  ParamVector s = cov.diagonal().cwiseMax(0.0).cwiseSqrt();
  return ParamSet::from_vector(s);
}

CalibrationInput input_from_field_data(Setting setting, const ImuSeries& imu,
                                       const std::vector<GnssFix>& gnss, const Site& site,
                                       const NoiseModel& noise) {
  CalibrationInput in;
  in.setting = setting;
  in.site = site;
  in.imu = imu;
  in.gnss = gnss;
  in.noise = noise;
  const std::vector<bool> rest = detect_rest(imu);
  in.reference.resize(imu.size());
  for (size_t k = 0; k < imu.size(); ++k) {
    in.reference[k].t_s = imu[k].t_s;
    in.reference[k].at_rest = rest[k];
  }
  return in;
}

}  // namespace imucal::calib
