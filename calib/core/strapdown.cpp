#include "calib/core/strapdown.hpp"

#include "calib/core/rotation.hpp"

namespace imucal::calib::core {

Strapdown::Strapdown(const EarthModel& earth) : earth_(earth) {
  const Site& site = earth_.site();
  // Central differences: the gravity model is smooth, so the linearisation error over the metres
  // (or kilometres, in the field) an INS moves is far below a micro-g.
  const double h = 10.0, dl = 1e-4;
  dg_dh_ = (EarthModel::normal_gravity_mps2(site.lat_rad, site.height_m + h) -
            EarthModel::normal_gravity_mps2(site.lat_rad, site.height_m - h)) /
           (2 * h);
  dg_dlat_ = (EarthModel::normal_gravity_mps2(site.lat_rad + dl, site.height_m) -
              EarthModel::normal_gravity_mps2(site.lat_rad - dl, site.height_m)) /
             (2 * dl);
}

double Strapdown::gravity_at(double lat_rad, double height_m) const {
  // The site's (surveyed or normal) value plus the normal-gravity gradients, so a surveyed value
  // stays exact at the site.
  const Site& site = earth_.site();
  return earth_.gravity_mps2() + dg_dh_ * (height_m - site.height_m) +
         dg_dlat_ * (lat_rad - site.lat_rad);
}

const Strapdown::LatTerms& Strapdown::lat_terms(double lat_rad) const {
  if (std::abs(lat_rad - cache_.lat_rad) > kLatCacheTolerance_rad) {
    cache_.lat_rad = lat_rad;
    cache_.cos_lat = std::cos(lat_rad);
    cache_.tan_lat = std::tan(lat_rad);
    cache_.R_N = EarthModel::radius_north_m(lat_rad);
    cache_.R_E = EarthModel::radius_east_m(lat_rad);
    cache_.w_ie_n = EarthModel::w_ie_n_at(lat_rad);
  }
  return cache_;
}

void Strapdown::step(NavState& s, const Eigen::Vector3d& dtheta_rad, const Eigen::Vector3d& dv_mps,
                     double dt_s) const {
  const LatTerms& L = lat_terms(s.lat_rad);
  const double RN = L.R_N + s.height_m;
  const double RE = L.R_E + s.height_m;
  const Eigen::Vector3d& w_ie_n = L.w_ie_n;
  const Eigen::Vector3d w_en_n(s.v_n_mps(1) / RE, -s.v_n_mps(0) / RN,
                               -s.v_n_mps(1) * L.tan_lat / RE);
  const Eigen::Vector3d w_in_n = w_ie_n + w_en_n;
  const Eigen::Vector3d zeta = w_in_n * dt_s;

  // Velocity first: it needs C_bn at the start of the interval (conventions.hpp).
  const Eigen::Vector3d f_dt_n = s.C_bn * dv_mps;
  const Eigen::Vector3d dv_n = f_dt_n - 0.5 * zeta.cross(f_dt_n);
  const Eigen::Vector3d g_n(0.0, 0.0, gravity_at(s.lat_rad, s.height_m));
  const Eigen::Vector3d v_old = s.v_n_mps;
  s.v_n_mps = v_old + dv_n + (g_n - (2.0 * w_ie_n + w_en_n).cross(v_old)) * dt_s;

  const Eigen::Vector3d v_mean = 0.5 * (v_old + s.v_n_mps);
  s.lat_rad += v_mean(0) / RN * dt_s;
  s.lon_rad += v_mean(1) / (RE * L.cos_lat) * dt_s;
  s.height_m -= v_mean(2) * dt_s;

  s.C_bn = rotvec_to_matrix<double>(Eigen::Vector3d(-zeta)) * s.C_bn *
           rotvec_to_matrix<double>(dtheta_rad);
  // Round-off in the product grows like sqrt(steps) * 1e-16; restoring orthonormality every 64
  // steps keeps it at the 1e-15 level at a sixty-fourth of the cost.
  if (++s.steps_since_normalize >= 64) {
    s.C_bn = orthonormalize(s.C_bn);
    s.steps_since_normalize = 0;
  }
}

}  // namespace imucal::calib::core
