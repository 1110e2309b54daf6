#include "calib/strapdown.hpp"

#include "calib/rotation.hpp"

namespace imucal::calib {

double Strapdown::gravity_at(double lat_rad, double height_m) const {
  const Site& site = earth_.site();
  return earth_.gravity_mps2() + EarthModel::normal_gravity_mps2(lat_rad, height_m) -
         EarthModel::normal_gravity_mps2(site.lat_rad, site.height_m);
}

void Strapdown::step(NavState& s, const Eigen::Vector3d& dtheta_rad, const Eigen::Vector3d& dv_mps,
                     double dt_s) const {
  const Eigen::Vector3d w_ie_n = EarthModel::w_ie_n_at(s.lat_rad);
  const Eigen::Vector3d w_en_n = EarthModel::w_en_n(s.v_n_mps, s.lat_rad, s.height_m);
  const Eigen::Vector3d w_in_n = w_ie_n + w_en_n;
  const Eigen::Vector3d zeta = w_in_n * dt_s;

  // Velocity first: it needs C_bn at the start of the interval (conventions.hpp).
  const Eigen::Vector3d dv_n =
      (Eigen::Matrix3d::Identity() - 0.5 * skew<double>(zeta)) * s.C_bn * dv_mps;
  const Eigen::Vector3d g_n(0.0, 0.0, gravity_at(s.lat_rad, s.height_m));
  const Eigen::Vector3d v_old = s.v_n_mps;
  s.v_n_mps = v_old + dv_n + (g_n - (2.0 * w_ie_n + w_en_n).cross(v_old)) * dt_s;

  const Eigen::Vector3d v_mean = 0.5 * (v_old + s.v_n_mps);
  const double RN = EarthModel::radius_north_m(s.lat_rad) + s.height_m;
  const double RE = EarthModel::radius_east_m(s.lat_rad) + s.height_m;
  s.lat_rad += v_mean(0) / RN * dt_s;
  s.lon_rad += v_mean(1) / (RE * std::cos(s.lat_rad)) * dt_s;
  s.height_m -= v_mean(2) * dt_s;

  s.C_bn = rotvec_to_matrix<double>(-zeta) * s.C_bn * rotvec_to_matrix<double>(dtheta_rad);
  s.C_bn = orthonormalize(s.C_bn);
}

}  // namespace imucal::calib
