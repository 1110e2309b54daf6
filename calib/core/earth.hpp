#pragma once
// WGS-84 Earth model: normal gravity (Somigliana with the free-air height term) or a surveyed
// local gravity, Earth rate and transport-rate helpers in NED.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <optional>

namespace imucal::calib::core {

namespace wgs84 {
constexpr double kSemiMajor_m = 6378137.0;
constexpr double kFlattening = 1.0 / 298.257223563;
constexpr double kEcc2 = kFlattening * (2.0 - kFlattening);
constexpr double kEarthRate_radps = 7.292115e-5;
constexpr double kGravityEquator_mps2 = 9.7803253359;
constexpr double kSomiglianaK = 0.00193185265241;  // (b*g_p)/(a*g_e) - 1
constexpr double kGM_m3ps2 = 3.986004418e14;
}  // namespace wgs84

/// Where the station (or a field site) is, and optionally its surveyed gravity.
struct Site {
  double lat_rad = 0.0;
  double lon_rad = 0.0;
  double height_m = 0.0;               ///< above the ellipsoid (depth = -height)
  std::optional<double> gravity_mps2;  ///< surveyed local gravity magnitude, if known
};

class EarthModel {
 public:
  explicit EarthModel(const Site& site);

  const Site& site() const { return site_; }
  /// Local gravity magnitude (surveyed if configured, else normal gravity at lat/height).
  double gravity_mps2() const { return g_mps2_; }
  /// Local gravity vector in NED: (0, 0, g).
  Eigen::Vector3d g_n() const { return {0.0, 0.0, g_mps2_}; }
  /// Earth rate in NED at the site's latitude.
  Eigen::Vector3d w_ie_n() const { return w_ie_n_; }
  /// Meridian (north) and prime-vertical (east) radii of curvature at latitude.
  static double radius_north_m(double lat_rad);
  static double radius_east_m(double lat_rad);
  /// Normal gravity (Somigliana + free-air correction to second order in height).
  static double normal_gravity_mps2(double lat_rad, double height_m);
  /// Transport rate w_en_n for velocity v_n at the given latitude and height.
  static Eigen::Vector3d w_en_n(const Eigen::Vector3d& v_n, double lat_rad, double height_m);
  static Eigen::Vector3d w_ie_n_at(double lat_rad);

 private:
  Site site_;
  double g_mps2_;
  Eigen::Vector3d w_ie_n_;
};

}  // namespace imucal::calib::core
