// The effects catalogue (ARCHITECTURE §7): every effect's forward model, as the simulator injects
// it, against a case derived by hand here (independent formulas: Eigen's AngleAxis for rotations,
// the textbook form of each effect) — not only a round trip. Runs use a perfect sensor (zero
// calibration parameters) and, where noise is not the point, no noise, so the simulator's output is
// the true increments plus the effect.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "calib/core/site_presets.hpp"
#include "calib/effects/catalogue.hpp"
#include "calib/effects/quantisation.hpp"
#include "calib/sim/truth_sim.hpp"
#include "tests/support/hand_profile.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;
using test_support::HandProfile;

namespace {

constexpr double kDt = 0.01;

/// A perfect unit: no calibration errors; noise and quantisation off unless a test turns them on.
UnitModel perfect_unit() {
  UnitModel u;
  u.noise.arw_rad_per_sqrt_s = 0.0;
  u.noise.vrw_mps_per_sqrt_s = 0.0;
  u.noise.dtheta_lsb_rad = 0.0;
  u.noise.dv_lsb_mps = 0.0;
  return u;
}

SimResult run(const sequences::MotionProfile& p, const UnitModel& u, bool noise = false,
              uint64_t seed = 1) {
  SimOptions so;
  so.noise = noise;
  so.seed = seed;
  return simulate(p, TableGeometry{}, demo_factory_site(), u, so);
}

/// Mean dv/dt and dθ/dt over the samples whose interval lies in [t0, t1].
struct Means {
  Eigen::Vector3d f = Eigen::Vector3d::Zero(), w = Eigen::Vector3d::Zero();
};
Means means(const SimResult& s, double t0, double t1) {
  Means m;
  int n = 0;
  for (const auto& x : s.imu)
    if (x.t_s - x.dt_s >= t0 && x.t_s <= t1) {
      m.f += x.dv_mps / x.dt_s;
      m.w += x.dtheta_rad / x.dt_s;
      ++n;
    }
  m.f /= n;
  m.w /= n;
  return m;
}

/// Mean of the sample-by-sample difference a - b of dv/dt and dθ/dt over [t0, t1] (same profile).
Means mean_difference(const SimResult& a, const SimResult& b, double t0, double t1) {
  Means m;
  int n = 0;
  for (size_t k = 0; k < a.imu.size(); ++k) {
    const ImuIncrement &x = a.imu[k], &y = b.imu[k];
    if (x.t_s - x.dt_s >= t0 && x.t_s <= t1) {
      m.f += (x.dv_mps - y.dv_mps) / x.dt_s;
      m.w += (x.dtheta_rad - y.dtheta_rad) / x.dt_s;
      ++n;
    }
  }
  m.f /= n;
  m.w /= n;
  return m;
}

double g_local() { return *demo_factory_site().gravity_mps2; }

Eigen::Matrix3d Rx(double a) {
  return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitX()).toRotationMatrix();
}
Eigen::Matrix3d Rz(double a) {
  return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

/// A rest at (outer, inner) degrees reached from (0, 0) by an outer then an inner turn.
sequences::MotionProfile rest_at(double outer_deg, double inner_deg, double rest_s = 20.0) {
  HandProfile h;
  h.rest(1.0);
  if (outer_deg != 0.0) h.rotate(true, outer_deg, 30.0, 30.0);
  if (inner_deg != 0.0) h.rotate(false, inner_deg, 30.0, 30.0);
  return h.rest(rest_s).build();
}
double rest_start(const sequences::MotionProfile& p) { return p.segments.back().t0_s + 1.0; }

/// Specific force the unit feels at rest for a body attitude C_bn (hand form of conventions.hpp:
/// dv = C_bnᵀ (f_n dt + ½ dt² ω_ie × f_n), f_n = -g_n).
Eigen::Vector3d rest_f_b(const Eigen::Matrix3d& C_bn, double g, double lat_rad) {
  const Eigen::Vector3d f_n(0, 0, -g);
  const Eigen::Vector3d w(7.292115e-5 * std::cos(lat_rad), 0.0, -7.292115e-5 * std::sin(lat_rad));
  return C_bn.transpose() * (f_n + 0.5 * kDt * w.cross(f_n));
}

}  // namespace

// K2 δf_i = K2_i f_i²: with body x down (outer 90°, inner 90°) f_x = -g and with x up (inner 270°)
// f_x = +g, so f_x moves by K2 g² on both sides; at a 45° tilt of y (outer 45°: down in body =
// (0, sin 45°, cos 45°)) f_y = -g/√2 and the shift is K2 g²/2.
TEST(Effects, AccelQuadraticK2ShiftsBy_K2_f_squared) {
  const double k2 = 20e-6 / kStandardGravity_mps2, g = g_local();
  UnitModel u = perfect_unit();
  for (const auto& [o, i, axis, f2] : std::vector<std::tuple<double, double, int, double>>{
           {90.0, 90.0, 0, g * g}, {90.0, 270.0, 0, g * g}, {45.0, 0.0, 1, g * g / 2.0}}) {
    const auto p = rest_at(o, i);
    u.effects = Effects{};
    const SimResult s0 = run(p, u);
    u.effects.accel_k2_per_mps2(axis) = k2;
    const SimResult s1 = run(p, u);
    const Means m0 = means(s0, rest_start(p), p.duration_s());
    // f² is g² (x down or up) or g²/2 (y at 45°) up to the Earth-rotation term of the increments
    // (1e-6); the shift is K2 f² to 1e-9 (differences taken sample by sample: the means of two
    // runs agree only to their rounding, ~1e-8 of the shift).
    EXPECT_NEAR(m0.f(axis) * m0.f(axis) / f2, 1.0, 2e-6) << o << "/" << i;
    EXPECT_NEAR(mean_difference(s1, s0, rest_start(p), p.duration_s()).f(axis),
                k2 * m0.f(axis) * m0.f(axis), 1e-9 * k2 * f2)
        << o << "/" << i;
  }
}

// Asymmetry δf_i = Kap_i |f_i|: the same +Kap g with x down and x up (outer 90°, inner 90° / 270°).
TEST(Effects, AccelAsymmetryIsTheSameOnBothSides) {
  const double kap = 12e-6, g = g_local();
  for (double inner : {90.0, 270.0}) {
    const auto p = rest_at(90.0, inner);
    UnitModel u = perfect_unit();
    const Means m0 = means(run(p, u), rest_start(p), p.duration_s());
    u.effects.accel_asym(0) = kap;
    const Means m1 = means(run(p, u), rest_start(p), p.duration_s());
    EXPECT_NEAR(std::abs(m0.f(0)), g, 1e-5);
    EXPECT_NEAR(m1.f(0) - m0.f(0), kap * g, 1e-6 * kap * g) << inner;
  }
}

// Size effect: accelerometer x 5 cm out along x; a constant-rate inner turn about body z (vertical)
// at ω gives accelerometer x the centripetal -ω² r (([ω×]² r)_x = -(ω_y² + ω_z²) r_x).
TEST(Effects, SizeEffectIsTheCentripetalTermWhileTurning) {
  const auto p = HandProfile().rest(5.0).rotate(false, 180.0, 20.0, 20.0).rest(5.0).build();
  UnitModel u = perfect_unit();
  u.effects.accel_lever_arm_m[0] = Eigen::Vector3d(0.05, 0.0, 0.0);
  const SimResult s = run(p, u);
  const double w = 20.0 * kDegToRad;
  double sum = 0.0;
  int n = 0;
  for (const auto& x : s.imu)
    if (std::abs(x.dtheta_rad.z() / x.dt_s - w) < 1e-4)
      sum += x.dv_mps.x() / x.dt_s, ++n;  // + Earth rate
  ASSERT_GT(n, 500);
  // Earth rate adds ~1e-9 relative; the tilt of body x is zero at outer 0.
  EXPECT_NEAR(sum / n, -w * w * 0.05, 2e-3 * w * w * 0.05);
}

// g-sensitivity δω = G f: with body x down f = (-g, 0, 0), so the mean rate moves by -g G[:, 0].
TEST(Effects, GyroGSensitivityMovesTheStaticRateByGf) {
  const auto p = rest_at(90.0, 90.0);
  UnitModel u = perfect_unit();
  const Means m0 = means(run(p, u), rest_start(p), p.duration_s());
  Eigen::Matrix3d G = Eigen::Matrix3d::Zero();
  G.col(0) = Eigen::Vector3d(0.02, -0.01, 0.005) * kDegPerHourToRadPerSec / kStandardGravity_mps2;
  u.effects.gyro_g_sens = G;
  const Means m1 = means(run(p, u), rest_start(p), p.duration_s());
  const Eigen::Vector3d expected = G * m0.f;  // f ≈ (-g, 0, 0)
  EXPECT_NEAR(m0.f(0), -g_local(), 1e-5);
  EXPECT_LT((m1.w - m0.w - expected).norm(), 1e-6 * expected.norm());
}

// Gyro-accel skew δf = t_GA (ω × f): turning about body z at outer 90° (z horizontal), ω ⊥ f, so
// every cruise sample's shift has magnitude t_GA ω g and the direction of ω × f.
TEST(Effects, GyroAccelSkewShiftsByTimeOffsetTimesOmegaCrossF) {
  HandProfile h;
  h.rest(1.0).rotate(true, 90.0, 30.0, 30.0).rest(1.0).rotate(false, 180.0, 10.0, 10.0).rest(1.0);
  const auto p = h.build();
  UnitModel u = perfect_unit();
  const SimResult s0 = run(p, u);
  u.effects.gyro_accel_skew_s = 1e-3;
  const SimResult s1 = run(p, u);
  const double w = 10.0 * kDegToRad;
  int n = 0;
  for (size_t k = 0; k < s0.imu.size(); ++k) {
    const Eigen::Vector3d om = s0.imu[k].dtheta_rad / kDt, f = s0.imu[k].dv_mps / kDt;
    if (std::abs(om.z() - w) > 1e-4) continue;  // cruise (ω_z includes a little Earth rate)
    const Eigen::Vector3d d = (s1.imu[k].dv_mps - s0.imu[k].dv_mps) / kDt;
    // By hand: at outer 90° down in body is (sin i, cos i, 0), so f = -g (sin i, cos i, 0) and
    // ω × f = ω g (cos i, -sin i, 0) — f at the interval start (dv is resolved there: a force fixed
    // in n reads as its start value). Tolerance: the Earth rate in ω (4e-4 of it).
    const double i0 = p.at(s0.imu[k].t_s - kDt).inner_rad;
    const Eigen::Vector3d hand =
        1e-3 * w * g_local() * Eigen::Vector3d(std::cos(i0), -std::sin(i0), 0);
    EXPECT_LT((d - hand).norm(), 1e-3 * hand.norm()) << k;
    EXPECT_LT((d - 1e-3 * om.cross(f)).norm(), 1e-9);
    ++n;
  }
  EXPECT_GT(n, 1000);
}

// Thermal warm-up b(t) = A exp(-t/τ): over the first τ seconds the mean shift is A (1 - e^-1).
TEST(Effects, ThermalDriftIsAnExponentialWarmUp) {
  const double tau = 60.0;
  const auto p = HandProfile().rest(tau).build();
  UnitModel u = perfect_unit();
  const Means m0 = means(run(p, u), 0.0, tau);
  u.effects.thermal_accel_mps2 = Eigen::Vector3d(20e-6 * kStandardGravity_mps2, 0, 0);
  u.effects.thermal_gyro_radps = Eigen::Vector3d(0, 0, 0.005 * kDegPerHourToRadPerSec);
  u.effects.thermal_tau_s = tau;
  const Means m1 = means(run(p, u), 0.0, tau);
  const double k = 1.0 - std::exp(-1.0);
  EXPECT_NEAR(m1.f(0) - m0.f(0), u.effects.thermal_accel_mps2(0) * k, 1e-12);
  EXPECT_NEAR(m1.w(2) - m0.w(2), u.effects.thermal_gyro_radps(2) * k, 1e-16);
}

// Bias instability: an undeclared Gauss-Markov bias (eq. 16-17) — its samples have variance σ² and
// lag-τ autocorrelation e^-1. The bias is the noisy run minus the noiseless one (no other noise
// here). Statistics pooled over the three axes: 3000 s at τ = 20 s are 150 correlation times per
// axis: the pooled variance scatters by ~8 % and the lag-τ correlation by ~0.04 (seeds 3, 5, 11-16:
// 0.84-1.12 and 0.32-0.42); the tolerances are ~3.5σ. Without noise (SimOptions::noise = false) the
// process is not drawn at all.
TEST(Effects, BiasInstabilityIsAGaussMarkovProcess) {
  const auto p = HandProfile().rest(3000.0).build();
  UnitModel u = perfect_unit();
  const SimResult s0 = run(p, u, false);
  u.effects.instability_gyro_radps = 0.001 * kDegPerHourToRadPerSec;
  u.effects.instability_accel_mps2 = 10e-6 * kStandardGravity_mps2;
  u.effects.instability_tau_s = 20.0;
  const SimResult s1 = run(p, u, true, 5);
  const size_t L = static_cast<size_t>(20.0 / kDt);
  for (const bool gyro : {false, true}) {
    const double sigma = gyro ? u.effects.instability_gyro_radps : u.effects.instability_accel_mps2;
    double var = 0.0, lag = 0.0;
    for (int i = 0; i < 3; ++i) {
      std::vector<double> b;
      for (size_t k = 0; k < s0.imu.size(); ++k)
        b.push_back(gyro ? (s1.imu[k].dtheta_rad(i) - s0.imu[k].dtheta_rad(i)) / kDt
                         : (s1.imu[k].dv_mps(i) - s0.imu[k].dv_mps(i)) / kDt);
      double mean = 0.0, v = 0.0, c = 0.0;
      for (double x : b) mean += x;
      mean /= static_cast<double>(b.size());
      for (size_t k = 0; k < b.size(); ++k) {
        v += (b[k] - mean) * (b[k] - mean);
        if (k + L < b.size()) c += (b[k] - mean) * (b[k + L] - mean);
      }
      var += v / static_cast<double>(b.size()) / 3.0;
      lag += c / static_cast<double>(b.size() - L) / 3.0;
    }
    EXPECT_NEAR(var / (sigma * sigma), 1.0, 0.3) << (gyro ? "gyro" : "accel");
    EXPECT_NEAR(lag / var, std::exp(-1.0), 0.15) << (gyro ? "gyro" : "accel");
  }
  const SimResult off = run(p, u, false);
  for (size_t k = 0; k < off.imu.size(); k += 997) {
    EXPECT_EQ(off.imu[k].dv_mps, s0.imu[k].dv_mps);
    EXPECT_EQ(off.imu[k].dtheta_rad, s0.imu[k].dtheta_rad);
  }
}

// Issue #50: the two roundings of a declared LSB on the same dithered input (white, σ = LSB).
// Carried: error variance LSB²/6, lag-1 autocovariance -LSB²/12, the sum of all increments within
// one LSB. Per sample: LSB²/12, none, and the sum's error a random walk of n·LSB²/12. The noise
// model's formulas give the same numbers.
TEST(Effects, APerSampleRoundingIsWhiteWhereACarriedOneIsAnticorrelated) {
  const double lsb = 1e-6;
  const int n = 200000;
  std::mt19937_64 rng(50);
  std::normal_distribution<double> noise(0.0, lsb);
  std::vector<double> x(n);
  for (double& v : x) v = 3.3e-6 + noise(rng);
  for (const LsbRounding r : {LsbRounding::kCarried, LsbRounding::kPerSample}) {
    const bool carried = r == LsbRounding::kCarried;
    Quantiser q{lsb, r};
    double v = 0.0, c1 = 0.0, sum_e = 0.0, prev = 0.0;
    for (int k = 0; k < n; ++k) {
      const double e = q.apply(Vec3<double>(x[k], 0.0, 0.0))(0) - x[k];
      v += e * e;
      if (k > 0) c1 += e * prev;
      sum_e += e;
      prev = e;
    }
    const double var = v / n, lag1 = c1 / (n - 1);
    std::printf("%s: variance %.4f LSB², lag-1 %.4f LSB², sum of the errors %.1f LSB\n",
                lsb_rounding_name(r), var / (lsb * lsb), lag1 / (lsb * lsb), sum_e / lsb);
    EXPECT_NEAR(var / (lsb * lsb / (carried ? 6.0 : 12.0)), 1.0, 0.02) << carried;
    EXPECT_NEAR(lag1 / (lsb * lsb / 12.0), carried ? -1.0 : 0.0, 0.03) << carried;
    EXPECT_NEAR(rounding_variance(lsb, r), lsb * lsb / (carried ? 6.0 : 12.0), 1e-25);
    EXPECT_NEAR(rounding_lag1_autocov(lsb, r), carried ? -lsb * lsb / 12.0 : 0.0, 1e-25);
    if (carried) {
      EXPECT_LE(std::abs(sum_e), lsb) << "the carried remainder keeps the sum within one LSB";
    } else {
      // A walk of σ √(n/12) LSB = 129 LSB at 200 000 samples (this seed's ends at -11 LSB): past
      // the one LSB a carried remainder allows.
      EXPECT_GT(std::abs(sum_e), 3.0 * lsb);
      EXPECT_NEAR(rounding_white_density(lsb, r, 0.01) * 0.01, lsb * lsb / 12.0, 1e-25);
    }
  }
}

// Quantisation with the remainder carried: every output is a whole number of LSBs, and (with the
// white noise dithering it) the rounding error e_k - e_{k-1} has variance LSB²/6 and lag-1
// autocovariance -LSB²/12. The same seed with and without the effect gives the same noise.
TEST(Effects, QuantisationRoundsToTheLsbWithACarriedRemainder) {
  const auto p = HandProfile().rest(300.0).build();
  UnitModel u = perfect_unit();
  u.noise.vrw_mps_per_sqrt_s = 10e-6 * kStandardGravity_mps2;  // dithers the rounding (σ 1e-5 m/s)
  u.noise.arw_rad_per_sqrt_s = 0.0015 * kDegToRad / 60.0;      // σ 4.4e-8 rad per sample
  const SimResult s0 = run(p, u, true, 3);
  const double q_dv = 1e-5, q_dth = 2e-8;
  u.effects.quant_dv_mps = q_dv;
  u.effects.quant_dtheta_rad = q_dth;
  const SimResult s1 = run(p, u, true, 3);
  for (const bool gyro : {false, true}) {
    const double q = gyro ? q_dth : q_dv;
    int off_grid = 0;
    double v = 0.0, c1 = 0.0;
    size_t n = 0, n1 = 0;
    for (int i = 0; i < 3; ++i) {
      std::vector<double> e;
      for (size_t k = 0; k < s1.imu.size(); ++k) {
        const double out = gyro ? s1.imu[k].dtheta_rad(i) : s1.imu[k].dv_mps(i);
        off_grid += std::abs(out / q - std::round(out / q)) > 1e-6 ? 1 : 0;
        e.push_back(out - (gyro ? s0.imu[k].dtheta_rad(i) : s0.imu[k].dv_mps(i)));
      }
      for (size_t k = 0; k < e.size(); ++k) {
        v += e[k] * e[k];
        if (k + 1 < e.size()) c1 += e[k] * e[k + 1];
      }
      n += e.size();
      n1 += e.size() - 1;
    }
    // The reference run is itself rounded at the declared LSBs (1e-7 m/s, 1e-9 rad): its own
    // error (variance LSB²/6) is 1e-4 (dv) and 4e-3 (dθ) of the effect's and ignored.
    EXPECT_EQ(off_grid, 0) << (gyro ? "gyro" : "accel");
    EXPECT_NEAR(v / static_cast<double>(n) / (q * q / 6.0), 1.0, 0.05) << (gyro ? "gyro" : "accel");
    EXPECT_NEAR(c1 / static_cast<double>(n1) / quantisation_lag1_autocov(q), 1.0, 0.08)
        << (gyro ? "gyro" : "accel");
  }
  // Without noise there is no output register rounding at all (deterministic exactness runs).
  const SimResult clean = run(p, u, false), clean0 = run(p, perfect_unit(), false);
  EXPECT_EQ(clean.imu[1234].dv_mps, clean0.imu[1234].dv_mps);
  EXPECT_EQ(clean.imu[1234].dtheta_rad, clean0.imu[1234].dtheta_rad);
}

// Table non-orthogonality: the inner axis leans by δ towards the outer axis, a' = (sin δ, 0, cos δ)
// in the outer-gimbal frame; at outer 90°, inner 90° the body attitude is Rx(90°) R(a', 90°) and
// gravity in the body follows it.
TEST(Effects, TableNonorthogonalityTiltsTheInnerAxis) {
  const double delta = 10.0 * kArcsecToRad;
  const auto p = rest_at(90.0, 90.0);
  UnitModel u = perfect_unit();
  u.effects.table_nonorthogonality_rad = delta;
  const Means m = means(run(p, u), rest_start(p), p.duration_s());
  const Eigen::Vector3d a(std::sin(delta), 0.0, std::cos(delta));
  const Eigen::Matrix3d C = Rx(kPi / 2) * Eigen::AngleAxisd(kPi / 2, a).toRotationMatrix();
  const Eigen::Vector3d expected = rest_f_b(C, g_local(), demo_factory_site().lat_rad);
  EXPECT_LT((m.f - expected).norm(), 1e-9) << m.f.transpose() << " vs " << expected.transpose();
  // And the lean is seen: the nominal table puts nothing on z; the lean about δ g (4.8e-4 m/s²).
  EXPECT_NEAR(std::abs(m.f.z()), delta * g_local(), 0.01 * delta * g_local());
}

// The leaning inner axis itself: at outer 90° the body turns from inner 0 to inner 90° about
// Rx(90°) a' = (sin δ, -cos δ, 0) in n — the nominal (0, -1, 0) tilted by δ towards the outer axis.
TEST(Effects, TableNonorthogonalityInnerAxisIsTiltedByDelta) {
  const double delta = 10.0 * kArcsecToRad;
  const auto p =
      HandProfile().rest(1.0).rotate(true, 90.0).rest(1.0).rotate(false, 90.0).rest(1.0).build();
  UnitModel u = perfect_unit();
  u.effects.table_nonorthogonality_rad = delta;
  const TableModel table{TableGeometry{}};
  std::vector<double> rest_mid;  // (0, 0), (90, 0), (90, 90)
  for (const auto& seg : p.segments)
    if (seg.kind == sequences::SegmentKind::kRest) rest_mid.push_back(0.5 * (seg.t0_s + seg.t1_s));
  ASSERT_EQ(rest_mid.size(), 3u);
  const double t_inner0 = rest_mid[1], t_inner90 = rest_mid[2];
  const Eigen::AngleAxisd turn(true_C_bn(p, table, u, t_inner90) *
                               true_C_bn(p, table, u, t_inner0).transpose());
  EXPECT_NEAR(turn.angle(), kPi / 2, 1e-12);
  EXPECT_LT((turn.axis() - Eigen::Vector3d(std::sin(delta), -std::cos(delta), 0.0)).norm(), 1e-12);
  u.effects = Effects{};
  const Eigen::AngleAxisd nominal(true_C_bn(p, table, u, t_inner90) *
                                  true_C_bn(p, table, u, t_inner0).transpose());
  EXPECT_NEAR(std::acos(turn.axis().dot(nominal.axis())), delta, 1e-9);
}

// Table wobble: platform tilt δ_o(inner) = Rz(-inner) (w_x, w_y, 0) between the outer gimbal and
// the inner rotation: at inner 0 the tilt is (w_x, w_y, 0), at inner 90° it is (w_y, -w_x, 0).
TEST(Effects, TableWobbleTiltsThePlatformOncePerRevolution) {
  const double wx = 8.0 * kArcsecToRad, wy = -5.0 * kArcsecToRad;
  for (double inner : {0.0, 90.0}) {
    const auto p = rest_at(60.0, inner);
    UnitModel u = perfect_unit();
    u.effects.table_wobble_rad = Eigen::Vector2d(wx, wy);
    const Means m = means(run(p, u), rest_start(p), p.duration_s());
    const Eigen::Vector3d tilt =
        inner == 0.0 ? Eigen::Vector3d(wx, wy, 0) : Eigen::Vector3d(wy, -wx, 0);
    const Eigen::Matrix3d C = Rx(60.0 * kDegToRad) *
                              Eigen::AngleAxisd(tilt.norm(), tilt.normalized()).toRotationMatrix() *
                              Rz(inner * kDegToRad);
    const Eigen::Vector3d expected = rest_f_b(C, g_local(), demo_factory_site().lat_rad);
    EXPECT_LT((m.f - expected).norm(), 1e-9) << inner;
  }
}

// Gravity error: the unit at rest feels g + δg (the station's configured g is wrong by δg).
TEST(Effects, GravityErrorChangesTheSpecificForceMagnitude) {
  const auto p = rest_at(0.0, 0.0);
  UnitModel u = perfect_unit();
  u.effects.gravity_error_mps2 = 50e-6 * kStandardGravity_mps2;
  const Means m = means(run(p, u), rest_start(p), p.duration_s());
  EXPECT_NEAR(m.f.norm(), g_local() + u.effects.gravity_error_mps2, 1e-9);
}

// Latitude error: at (0, 0) (body = NED) the gyros read the Earth rate of the true latitude,
// Ω (cos φ, 0, -sin φ) with φ = configured + δφ.
TEST(Effects, LatitudeErrorSplitsTheEarthRateAtTheTrueLatitude) {
  const auto p = rest_at(0.0, 0.0);
  UnitModel u = perfect_unit();
  u.effects.latitude_error_rad = 1.0 / 60.0 * kDegToRad;
  const Means m = means(run(p, u), rest_start(p), p.duration_s());
  const double phi = demo_factory_site().lat_rad + u.effects.latitude_error_rad;
  const Eigen::Vector3d expected(7.292115e-5 * std::cos(phi), 0.0, -7.292115e-5 * std::sin(phi));
  EXPECT_LT((m.w - expected).norm(), 1e-13);
}

// Table time offset: during a constant-rate move the encoder log lags the motion by ω δt.
TEST(Effects, TableTimeOffsetDelaysTheEncoderLog) {
  const auto p = HandProfile().rest(2.0).rotate(true, 90.0, 10.0, 20.0).rest(2.0).build();
  UnitModel u = perfect_unit();
  const SimResult s0 = run(p, u);
  u.effects.table_time_offset_s = 0.02;
  const SimResult s1 = run(p, u);
  // Mid-cruise (t = 2 + 0.5 + 4 s): outer moves at 10 °/s.
  const size_t k = static_cast<size_t>(6.5 / kDt);
  EXPECT_NEAR(s0.table[k].outer_rad - s1.table[k].outer_rad, 10.0 * kDegToRad * 0.02, 1e-9);
  // The IMU stream itself does not change.
  EXPECT_EQ(s0.imu[k].dtheta_rad, s1.imu[k].dtheta_rad);
}

TEST(Effects, CatalogueNamesAndSpecsAreOneVocabulary) {
  EXPECT_EQ(effect_catalogue().size(), static_cast<size_t>(kNumEffects));
  Effects fx;
  apply_effect_spec(fx, "thermal_drift=1e-4,0,0,0,0,2e-8");  // τ left out: default kept
  EXPECT_EQ(fx.thermal_accel_mps2(0), 1e-4);
  EXPECT_EQ(fx.thermal_tau_s, Effects{}.thermal_tau_s);
  EXPECT_EQ(fx.active_names(), std::vector<std::string>{"thermal_drift"});
  EXPECT_THROW(apply_effect_spec(fx, "thermal_drift=1"), std::invalid_argument);
  EXPECT_THROW(apply_effect_spec(fx, "bias_instability=-1,0"), std::invalid_argument);
  EXPECT_THROW(apply_effect_spec(fx, "nope=1"), std::invalid_argument);
  EXPECT_THROW(apply_effect_spec(fx, "gravity_error=abc"), std::invalid_argument);
  // Magnitudes: the typical pattern of a relative effect is 1 x typical.
  const EffectInfo& t = effect_info(EffectId::kThermalDrift);
  EXPECT_NEAR(t.magnitude(Eigen::Map<const Eigen::VectorXd>(t.typical.data(), t.size())), 1.0,
              1e-12);
}
