// The evaluation's ZUPT-aided INS (calib/checks/zupt_ins.hpp) reopens its attitude uncertainty
// when the unit comes to rest after motion: the tilt always (tilt_sigma_after_motion_rad), the
// heading only when heading_sigma_after_motion_rad asks for it (issue #26's
// evaluation_heading_reopen: an INS that re-finds its heading at every rest). A unit at rest, one
// filter interval of motion, then rest again: the heading variance grows by exactly σ² when asked
// (one ZUPT hardly observes heading), and not at all otherwise; bad values are refused.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "calib/checks/zupt_ins.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/site_presets.hpp"

namespace imucal::calib {
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
namespace {

/// The heading variance before the motion and after the first aided epoch of the next rest.
std::pair<double, double> heading_variance_around_a_motion(double heading_sigma_rad) {
  const Site site = demo_factory_site();
  const EarthModel earth(site);
  NoiseModel noise;
  noise.arw_rad_per_sqrt_s = 1e-7;
  noise.vrw_mps_per_sqrt_s = 1e-5;
  ZuptInsOptions opt;
  opt.heading_sigma_after_motion_rad = heading_sigma_rad;
  ZuptIns ins(earth, noise, opt);
  NavState nav0;
  nav0.lat_rad = site.lat_rad;
  nav0.lon_rad = site.lon_rad;
  nav0.height_m = site.height_m;
  ins.initialize(nav0, Eigen::Vector3d(1e-6, 1e-6, 1e-6).cwiseAbs2().asDiagonal());
  // At rest the accelerometers read the reaction to gravity and the gyros Earth rate (body = NED).
  const double dt_s = 0.01;
  const Eigen::Vector3d dv_mps = -earth.g_n() * dt_s;
  const Eigen::Vector3d dtheta_rad = earth.w_ie_n() * dt_s;
  for (int k = 0; k < 50; ++k) ins.step(dtheta_rad, dv_mps, dt_s, true);
  const double before = ins.attitude_covariance()(2, 2);
  for (int k = 0; k < 10; ++k) ins.step(dtheta_rad, dv_mps, dt_s, false);
  for (int k = 0; k < 10; ++k) ins.step(dtheta_rad, dv_mps, dt_s, true);
  return {before, ins.attitude_covariance()(2, 2)};
}

TEST(ZuptInsHeading, ReopenedAfterMotionOnlyWhenAsked) {
  const auto [held_before, held_after] = heading_variance_around_a_motion(0.0);
  // Held: only ARW over 0.2 s adds to it.
  EXPECT_NEAR(held_after, held_before, 1e-13);
  const double sigma = 10e-3;
  const auto [before, after] = heading_variance_around_a_motion(sigma);
  EXPECT_NEAR(after - before, sigma * sigma, 0.01 * sigma * sigma);
}

TEST(ZuptInsHeading, ANegativeOrNonFiniteHeadingSigmaIsRefused) {
  const EarthModel earth(demo_factory_site());
  NoiseModel noise;
  noise.arw_rad_per_sqrt_s = 1e-7;
  noise.vrw_mps_per_sqrt_s = 1e-5;
  ZuptInsOptions opt;
  for (double bad : {-1e-3, std::nan("")}) {
    opt.heading_sigma_after_motion_rad = bad;
    try {
      ZuptIns ins(earth, noise, opt);
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("heading_sigma_after_motion_rad"), std::string::npos);
    }
  }
}

}  // namespace
}  // namespace imucal::calib
