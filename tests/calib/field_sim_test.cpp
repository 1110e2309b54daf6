// Field-run simulator (calib/sim/field_sim.hpp): physics checked against hand-derived values and an
// independent strapdown integration; placement, timing and GNSS statistics; refusals.
#include "calib/sim/field_sim.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/core/strapdown.hpp"
#include "sequences/library.hpp"

namespace imucal::calib {
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;
namespace {

Site field_site() {
  Site s = demo_factory_site();
  s.gravity_mps2.reset();  // normal gravity, as at a customer site
  return s;
}

UnitModel ideal_unit() {
  UnitModel u = default_unit();
  u.params = ParamSet{};
  return u;
}

FieldSimOptions options(Setting s, bool noise) {
  FieldSimOptions o;
  o.setting = s;
  o.noise = noise;
  o.seed = 5;
  return o;
}

const sequences::MotionProfile& short_profile() {
  static const sequences::MotionProfile p = sequences::load_profile("short");
  return p;
}

TEST(FieldSim, OnLandAtRestTheIncrementsAreGravityAndEarthRate) {
  const FieldSimResult r =
      simulate_field(short_profile(), field_site(), ideal_unit(), options(Setting::kLand, false));
  ASSERT_FALSE(r.imu.empty());
  const Site site = field_site();
  const double g = EarthModel::normal_gravity_mps2(site.lat_rad, site.height_m);
  const Eigen::Vector3d w_ie_n = EarthModel::w_ie_n_at(site.lat_rad);
  size_t checked = 0;
  for (size_t k = 1; k < r.imu.size(); k += 97) {
    if (!r.true_rest[k] || !r.true_rest[k - 1]) continue;
    const ImuIncrement& s = r.imu[k];
    // |f| = g and ω_b = C_bnᵀ ω_ie (attitude constant at rest on land).
    EXPECT_NEAR(s.dv_mps.norm() / s.dt_s, g, 1e-9 * g) << k;
    const Eigen::Vector3d w_b = r.C_bn[k].transpose() * w_ie_n;
    EXPECT_LT((s.dtheta_rad / s.dt_s - w_b).norm(), 1e-12) << k;
    // Specific force points up: C_bn f_b = (0, 0, -g).
    EXPECT_LT((r.C_bn[k] * s.dv_mps / s.dt_s - Eigen::Vector3d(0, 0, -g)).norm(), 1e-6 * g) << k;
    ++checked;
  }
  EXPECT_GT(checked, 100u);
}

/// Integrates the noise-free increments with the product's strapdown from the true initial
/// state and returns the largest attitude error (rad) and the final position error (m).
std::pair<double, double> strapdown_errors(const FieldSimResult& r, const Site& site,
                                           const FieldSimOptions& o) {
  const EarthModel earth(site);
  const Strapdown ins(earth);
  NavState nav;
  // The state at t = 0 is the attitude before the first sample; C_bn[0] is at the first sample's
  // end, so start from sample 0 and integrate from sample 1.
  nav.C_bn = r.C_bn[0];
  nav.lat_rad = site.lat_rad;
  nav.lon_rad = site.lon_rad;
  nav.height_m = site.height_m;
  double max_att = 0.0;
  // Platform velocity and position at the first sample's end from the GNSS-free truth: on land 0;
  // at sea start from rest by reading them off a second simulation is not possible, so the sea
  // check runs with drift and heave off and rocking on (attitude-only motion).
  (void)o;
  for (size_t k = 1; k < r.imu.size(); ++k) {
    ins.step(nav, r.imu[k].dtheta_rad, r.imu[k].dv_mps, r.imu[k].dt_s);
    max_att = std::max(max_att, matrix_to_rotvec(nav.C_bn * r.C_bn[k].transpose()).norm());
  }
  const double RN = EarthModel::radius_north_m(site.lat_rad);
  const double pos = std::hypot((nav.lat_rad - site.lat_rad) * RN, site.height_m - nav.height_m);
  return {max_att, pos};
}

TEST(FieldSim, StrapdownFollowsTheTruthOnLandAndOnARockingDeck) {
  const Site site = field_site();
  FieldSimOptions o = options(Setting::kLand, false);
  auto [att, pos] =
      strapdown_errors(simulate_field(short_profile(), site, ideal_unit(), o), site, o);
  EXPECT_LT(att, 1e-8);
  // Exact increments: the position drift is the strapdown's own (second-order) integration error.
  EXPECT_LT(pos, 1e-2);
  o = options(Setting::kSea, false);
  o.drift_amplitude_m = 0.0;
  o.heave_amplitude_m = 0.0;
  o.rock_amplitude_deg = 0.5;
  std::tie(att, pos) =
      strapdown_errors(simulate_field(short_profile(), site, ideal_unit(), o), site, o);
  EXPECT_LT(att, 1e-8);
  EXPECT_LT(pos, 1e-2);
}

TEST(FieldSim, DriftingDeckVelocityIsMeasured) {
  // With DP drift the strapdown, started at the platform's true initial velocity, ends where the
  // platform is: the velocity increments carry the translation.
  const Site site = field_site();
  FieldSimOptions o = options(Setting::kSea, false);
  o.rock_amplitude_deg = 0.0;
  const FieldSimResult r = simulate_field(short_profile(), site, ideal_unit(), o);
  // The GNSS noise is white with σ = 0.3 m around the truth; its mean over the run is ≈ 0, so
  // the fixes' mean displacement from the site is bounded by the drift amplitude.
  double n_mean = 0.0;
  const double RN = EarthModel::radius_north_m(site.lat_rad) + site.height_m;
  for (const auto& g : r.gnss) n_mean += (g.lat_rad - site.lat_rad) * RN / r.gnss.size();
  EXPECT_LT(std::abs(n_mean), o.drift_amplitude_m + 0.1);
  // The speed the accelerometers see: integrate C_bn dv + g over the run (levelled frame).
  Eigen::Vector3d v = Eigen::Vector3d::Zero(), v_max = Eigen::Vector3d::Zero();
  const double g = EarthModel::normal_gravity_mps2(site.lat_rad, site.height_m);
  for (size_t k = 1; k < r.imu.size(); ++k) {
    v += r.C_bn[k - 1] * r.imu[k].dv_mps + Eigen::Vector3d(0, 0, g) * r.imu[k].dt_s;
    v_max = v_max.cwiseMax(v.cwiseAbs());
  }
  // The drift speed is A ω = 2 m · 2π/300 s ≈ 0.042 m/s: the velocity change must reach that
  // order (and the Coriolis/transport terms ignored here are < 1e-3 m/s over the run).
  const double vd = o.drift_amplitude_m * 2.0 * kPi / o.drift_period_s;
  EXPECT_GT(v_max.head<2>().maxCoeff(), 0.5 * vd);
  EXPECT_LT(v_max.head<2>().maxCoeff(), 2.5 * vd + 0.02);
}

TEST(FieldSim, PlacementTimingAndGnssStatistics) {
  FieldSimOptions o = options(Setting::kSea, true);
  o.placement_sigma_deg = 2.0;
  o.duration_jitter = 0.2;
  const sequences::MotionProfile& p = short_profile();
  const FieldSimResult r = simulate_field(p, field_site(), ideal_unit(), o);
  // Rest durations within the jitter of the profile's.
  std::vector<double> rests;
  for (const auto& s : p.segments)
    if (s.kind == sequences::SegmentKind::kRest) rests.push_back(s.t1_s - s.t0_s);
  ASSERT_EQ(r.rest_spans.size(), rests.size());
  for (size_t i = 0; i < rests.size(); ++i) {
    const double d = r.rest_spans[i].second - r.rest_spans[i].first;
    EXPECT_GE(d, 0.8 * rests[i] - 1e-9);
    EXPECT_LE(d, 1.2 * rests[i] + 1e-9);
  }
  // GNSS: inside the IMU span, 1 Hz, noise σ 0.3 m about the drift (chi-square bound on the
  // residual after removing the slow drift by differencing consecutive fixes: var(Δ) = 2σ²).
  ASSERT_GT(r.gnss.size(), 100u);
  EXPECT_GE(r.gnss.front().t_s, r.imu.front().t_s - r.imu.front().dt_s);
  EXPECT_LE(r.gnss.back().t_s, r.imu.back().t_s);
  const double RN = EarthModel::radius_north_m(field_site().lat_rad) + field_site().height_m;
  double s2 = 0.0;
  for (size_t i = 1; i < r.gnss.size(); ++i) {
    const double d = (r.gnss[i].lat_rad - r.gnss[i - 1].lat_rad) * RN;
    s2 += d * d;
  }
  const double sigma = std::sqrt(s2 / (2.0 * (r.gnss.size() - 1)));
  EXPECT_NEAR(sigma, 0.3, 0.3 * 4.0 / std::sqrt(2.0 * r.gnss.size()));
}

TEST(FieldSim, RefusesFactoryTableEffectsAndBadOptions) {
  auto message = [](Setting s, UnitModel u, FieldSimOptions o) {
    o.setting = s;
    try {
      simulate_field(short_profile(), field_site(), u, o);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(message(Setting::kFactory, ideal_unit(), {}).find("factory"), std::string::npos);
  UnitModel u = ideal_unit();
  u.effects.table_wobble_rad = Eigen::Vector2d(1e-5, 0);
  EXPECT_NE(message(Setting::kLand, u, {}).find("table effects"), std::string::npos);
  FieldSimOptions o;
  o.duration_jitter = 0.95;
  EXPECT_NE(message(Setting::kLand, ideal_unit(), o).find("duration_jitter"), std::string::npos);
  o = {};
  o.gnss_sigma_m = 0.0;
  EXPECT_NE(message(Setting::kSea, ideal_unit(), o).find("gnss_sigma_m"), std::string::npos);
}

}  // namespace
}  // namespace imucal::calib
