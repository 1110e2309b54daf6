#pragma once
// Strapdown INS in NED on increments (paper eq. 1-5), shared by AINS, NLSQ and evaluation.
#include <Eigen/Core>

#include "calib/core/earth.hpp"
#include "calib/core/imu_increment.hpp"

namespace imucal::calib::core {

struct NavState {
  Eigen::Matrix3d C_bn = Eigen::Matrix3d::Identity();
  Eigen::Vector3d v_n_mps = Eigen::Vector3d::Zero();
  double lat_rad = 0.0;
  double lon_rad = 0.0;
  double height_m = 0.0;
  int steps_since_normalize = 0;  ///< re-orthonormalisation bookkeeping (round-off only)
};

class Strapdown {
 public:
  explicit Strapdown(const EarthModel& earth);

  /// Advance by one *compensated* increment (error model already removed).
  /// Attitude: C_bn(k) = exp(-[ω_in dt x]) C_bn(k-1) exp([dθ x])            (eq. 5 integrated)
  /// Velocity: Δv_n = (I - ½[ω_in dt x]) C_bn(k-1) dv + (g_n - (2ω_ie+ω_en) x v) dt  (eq. 2)
  /// Position: eq. 4 with the mean velocity over the step.
  void step(NavState& s, const Eigen::Vector3d& dtheta_rad, const Eigen::Vector3d& dv_mps,
            double dt_s) const;

  /// Gravity at a height near the site: the site's (surveyed or normal) value plus the
  /// normal-gravity height gradient, so a surveyed value stays exact at the site height.
  double gravity_at(double lat_rad, double height_m) const;

  const EarthModel& earth() const { return earth_; }

 private:
  /// Latitude-dependent terms, recomputed only when the latitude moved by more than
  /// kLatCacheTolerance_rad (≈ 6 m): Earth rate and radii change by < 1e-6 relative over that.
  struct LatTerms {
    double lat_rad = 1e9;
    double cos_lat = 0, tan_lat = 0, R_N = 0, R_E = 0;
    Eigen::Vector3d w_ie_n = Eigen::Vector3d::Zero();
  };
  static constexpr double kLatCacheTolerance_rad = 1e-6;
  const LatTerms& lat_terms(double lat_rad) const;

  EarthModel earth_;
  double dg_dh_ = 0.0;    ///< normal-gravity height gradient at the site, 1/s^2
  double dg_dlat_ = 0.0;  ///< normal-gravity latitude gradient at the site, m/s^2/rad
  mutable LatTerms cache_;
};

}  // namespace imucal::calib::core
