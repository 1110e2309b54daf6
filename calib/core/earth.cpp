#include "calib/core/earth.hpp"

#include <cmath>

namespace imucal::calib::core {

EarthModel::EarthModel(const Site& site)
    : site_(site),
      g_mps2_(site.gravity_mps2 ? *site.gravity_mps2
                                : normal_gravity_mps2(site.lat_rad, site.height_m)),
      w_ie_n_(w_ie_n_at(site.lat_rad)) {}

double EarthModel::radius_north_m(double lat_rad) {
  const double s = std::sin(lat_rad);
  const double d = 1.0 - wgs84::kEcc2 * s * s;
  return wgs84::kSemiMajor_m * (1.0 - wgs84::kEcc2) / (d * std::sqrt(d));
}

double EarthModel::radius_east_m(double lat_rad) {
  const double s = std::sin(lat_rad);
  return wgs84::kSemiMajor_m / std::sqrt(1.0 - wgs84::kEcc2 * s * s);
}

double EarthModel::normal_gravity_mps2(double lat_rad, double height_m) {
  using namespace wgs84;
  const double s2 = std::sin(lat_rad) * std::sin(lat_rad);
  const double g0 = kGravityEquator_mps2 * (1.0 + kSomiglianaK * s2) / std::sqrt(1.0 - kEcc2 * s2);
  // Free-air term to second order (Groves eq. 2.140 form).
  const double a = kSemiMajor_m, f = kFlattening;
  const double m = kEarthRate_radps * kEarthRate_radps * a * a * (a * (1.0 - f)) / kGM_m3ps2;
  return g0 * (1.0 - 2.0 / a * (1.0 + f + m - 2.0 * f * s2) * height_m +
               3.0 / (a * a) * height_m * height_m);
}

Eigen::Vector3d EarthModel::w_ie_n_at(double lat_rad) {
  return {wgs84::kEarthRate_radps * std::cos(lat_rad), 0.0,
          -wgs84::kEarthRate_radps * std::sin(lat_rad)};
}

Eigen::Vector3d EarthModel::w_en_n(const Eigen::Vector3d& v_n, double lat_rad, double height_m) {
  const double RN = radius_north_m(lat_rad) + height_m;
  const double RE = radius_east_m(lat_rad) + height_m;
  return {v_n(1) / RE, -v_n(0) / RN, -v_n(1) * std::tan(lat_rad) / RE};
}

}  // namespace imucal::calib::core
