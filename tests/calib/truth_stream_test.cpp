// The streaming truth simulator against the batch one (same physics, so the same increments when
// both see the same motion), and its noise against the NoiseModel it was given.
#include "calib/sim/truth_stream.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "calib/core/earth.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/effects/catalogue.hpp"
#include "tests/support/hand_profile.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

namespace {

sequences::MotionProfile two_axis_profile() {
  return test_support::HandProfile(10.0, -20.0)
      .rest(1.5)
      .rotate(true, 90.0, 20.0, 15.0)
      .rest(0.73)
      .rotate(false, -135.0, 30.0, 25.0)
      .rest(0.5)
      .build();
}

UnitModel unit_with_effects() {
  UnitModel u = default_unit();
  u.effects.accel_k2_per_mps2 << 1e-6, -2e-6, 1.5e-6;
  u.effects.accel_asym << 2e-5, 0.0, -1e-5;
  u.effects.gyro_g_sens(0, 2) = 3e-6;
  u.effects.accel_lever_arm_m[0] << 0.0, 0.03, 0.01;
  u.effects.accel_lever_arm_m[2] << 0.02, 0.0, 0.0;
  return u;
}

/// Every catalogue effect on at once (ARCHITECTURE §7, typical sizes or larger), the stochastic
/// ones only acting with noise on. The table time offset changes only the batch form's encoder log.
/// All but rest_tremor, which a stream refuses (a hand's motion fades out before its rest's end,
/// which a stream does not know in advance; RestTremor.TableSimulatorTurnsGyrosAndAccelerometers*).
UnitModel unit_with_every_effect() {
  UnitModel u = unit_with_effects();
  Effects& fx = u.effects;
  fx.gyro_accel_skew_s = 5e-4;
  fx.thermal_accel_mps2 << 20e-6 * kStandardGravity_mps2, -10e-6 * kStandardGravity_mps2, 0.0;
  fx.thermal_gyro_radps << 0.0, 0.005 * kDegPerHourToRadPerSec, -0.003 * kDegPerHourToRadPerSec;
  fx.thermal_tau_s = 2.0;  // the warm-up visible within the few seconds of the profile
  fx.instability_gyro_radps = 0.002 * kDegPerHourToRadPerSec;
  fx.instability_accel_mps2 = 20e-6 * kStandardGravity_mps2;
  fx.instability_tau_s = 1.0;
  fx.quant_dtheta_rad = 1e-7;
  fx.quant_dv_mps = 1e-5;
  fx.output_filter_gyro = 0.3;
  fx.output_filter_accel = 0.5;
  fx.table_time_offset_s = 0.005;
  fx.table_nonorthogonality_rad = 8.0 * kArcsecToRad;
  fx.table_wobble_rad << 4.0 * kArcsecToRad, -3.0 * kArcsecToRad;
  fx.gravity_error_mps2 = 40e-6 * kStandardGravity_mps2;
  fx.latitude_error_rad = 1.0 / 60.0 * kDegToRad;
  for (const EffectInfo& e : effect_catalogue())
    EXPECT_EQ(fx.active(e.id), e.id != EffectId::kRestTremor) << e.name;
  return u;
}

/// Runs the stream over the profile, feeding it the acceleration breakpoints inside each interval
/// and recording every time state_at was asked for.
ImuSeries stream_profile(const sequences::MotionProfile& p, const UnitModel& unit,
                         const SimOptions& o,
                         std::vector<std::pair<double, double>>* intervals = nullptr,
                         std::vector<std::vector<double>>* calls = nullptr) {
  TruthStream stream(TableGeometry{}, demo_factory_site(), unit, o);
  const auto n = static_cast<size_t>(std::floor(p.duration_s() * o.rate_hz + 1e-9));
  const std::vector<double> breaks = p.breakpoints();
  ImuSeries out;
  for (size_t k = 0; k < n; ++k) {
    const double t0 = stream.interval_start_s(), t1 = stream.next_time_s();
    std::vector<double> inside;
    for (double b : breaks)
      if (b > t0 && b < t1) inside.push_back(b);
    std::vector<double> asked;
    out.push_back(stream.next(
        [&](double t) {
          asked.push_back(t);
          return p.at(t);
        },
        inside));
    if (intervals) intervals->emplace_back(t0, t1);
    if (calls) calls->push_back(asked);
  }
  return out;
}

}  // namespace

TEST(TruthStream, NoiselessEqualsBatchSimulatorWithEffects) {
  const auto p = two_axis_profile();
  const UnitModel unit = unit_with_effects();
  SimOptions o;
  o.noise = false;
  const SimResult batch = simulate(p, TableGeometry{}, demo_factory_site(), unit, o);
  std::vector<std::pair<double, double>> intervals;
  std::vector<std::vector<double>> calls;
  const ImuSeries s = stream_profile(p, unit, o, &intervals, &calls);
  ASSERT_EQ(s.size(), batch.imu.size());
  ASSERT_GT(s.size(), 400u);

  // Both evaluate the same formulas on the same states; only the order of a few floating-point
  // operations may differ, so the difference is bounded by a few ulps of the magnitudes involved:
  // dθ ~ (table rate + Earth rate) dt, dv ~ (g + lever-arm terms) dt.
  const double eps = std::numeric_limits<double>::epsilon();
  const double dt = 1.0 / o.rate_hz;
  const double max_rate = 30.0 * kDegToRad + 7.3e-5;
  const double tol_dth = 64.0 * eps * max_rate * dt;
  const double tol_dv = 64.0 * eps * (10.0 + 1.0) * dt;
  for (size_t k = 0; k < s.size(); ++k) {
    EXPECT_DOUBLE_EQ(s[k].t_s, batch.imu[k].t_s);
    EXPECT_DOUBLE_EQ(s[k].dt_s, batch.imu[k].dt_s);
    ASSERT_LE((s[k].dtheta_rad - batch.imu[k].dtheta_rad).lpNorm<Eigen::Infinity>(), tol_dth) << k;
    ASSERT_LE((s[k].dv_mps - batch.imu[k].dv_mps).lpNorm<Eigen::Infinity>(), tol_dv) << k;
  }
  // The caller is asked for non-decreasing times inside its interval (a PLC steps forward only).
  double last = -1.0;
  for (size_t k = 0; k < calls.size(); ++k) {
    ASSERT_FALSE(calls[k].empty());
    for (double t : calls[k]) {
      EXPECT_GE(t, last);
      EXPECT_GE(t, intervals[k].first);
      EXPECT_LE(t, intervals[k].second);
      last = t;
    }
    EXPECT_EQ(calls[k].back(), intervals[k].second);  // ends at the sample time
  }
}

// Every effect of the catalogue at once, noiseless: the deterministic effects (sensor, table, site)
// stream exactly like the batch form injects them — and they really are in the data (compared with
// the same unit without them).
TEST(TruthStream, NoiselessEqualsBatchSimulatorWithEveryEffect) {
  const auto p = two_axis_profile();
  const UnitModel unit = unit_with_every_effect();
  SimOptions o;
  o.noise = false;
  const SimResult batch = simulate(p, TableGeometry{}, demo_factory_site(), unit, o);
  const ImuSeries s = stream_profile(p, unit, o);
  ASSERT_EQ(s.size(), batch.imu.size());
  const double eps = std::numeric_limits<double>::epsilon(), dt = 1.0 / o.rate_hz;
  const double tol_dth = 64.0 * eps * (30.0 * kDegToRad + 7.3e-5) * dt;
  const double tol_dv = 64.0 * eps * (10.0 + 1.0) * dt;
  for (size_t k = 0; k < s.size(); ++k) {
    ASSERT_LE((s[k].dtheta_rad - batch.imu[k].dtheta_rad).lpNorm<Eigen::Infinity>(), tol_dth) << k;
    ASSERT_LE((s[k].dv_mps - batch.imu[k].dv_mps).lpNorm<Eigen::Infinity>(), tol_dv) << k;
  }
  const SimResult without = simulate(p, TableGeometry{}, demo_factory_site(), default_unit(), o);
  double d_dv = 0.0, d_dth = 0.0;
  for (size_t k = 0; k < s.size(); ++k) {
    d_dv = std::max(d_dv, (s[k].dv_mps - without.imu[k].dv_mps).norm());
    d_dth = std::max(d_dth, (s[k].dtheta_rad - without.imu[k].dtheta_rad).norm());
  }
  EXPECT_GT(d_dv, 1e3 * tol_dv);
  EXPECT_GT(d_dth, 1e3 * tol_dth);
}

// ... and with noise: the undeclared Gauss-Markov bias draws from the same generator in the same
// order, and the coarser real LSBs round the same sums (a rounding may flip where the two forms'
// last bits differ: one LSB, carried into the next sample).
TEST(TruthStream, NoisyEqualsBatchSimulatorWithEveryEffect) {
  const auto p = two_axis_profile();
  const UnitModel unit = unit_with_every_effect();
  SimOptions o;
  o.seed = 77;
  const SimResult batch = simulate(p, TableGeometry{}, demo_factory_site(), unit, o);
  const ImuSeries s = stream_profile(p, unit, o);
  ASSERT_EQ(s.size(), batch.imu.size());
  int differ = 0;
  for (size_t k = 0; k < s.size(); ++k) {
    const double e_th = (s[k].dtheta_rad - batch.imu[k].dtheta_rad).lpNorm<Eigen::Infinity>();
    const double e_v = (s[k].dv_mps - batch.imu[k].dv_mps).lpNorm<Eigen::Infinity>();
    ASSERT_LE(e_th, 1.5 * unit.effects.quant_dtheta_rad) << k;
    ASSERT_LE(e_v, 1.5 * unit.effects.quant_dv_mps) << k;
    differ += (e_th > 0.0 || e_v > 0.0) ? 1 : 0;
  }
  EXPECT_LT(differ, 10);
}

TEST(TruthStream, SizeEffectQuadratureNeedsTheBreakpoints) {
  // Without the acceleration jumps the quadrature straddles a discontinuity of ω̇: the dv of those
  // intervals must differ from the batch result by about the lever-arm force jump |Δω̇| r dt
  // (here 15 °/s² × 3 cm × 10 ms ≈ 8e-5 m/s), while intervals without a jump agree.
  const auto p = two_axis_profile();
  const UnitModel unit = unit_with_effects();
  SimOptions o;
  o.noise = false;
  const SimResult batch = simulate(p, TableGeometry{}, demo_factory_site(), unit, o);
  TruthStream stream(TableGeometry{}, demo_factory_site(), unit, o);
  const std::vector<double> breaks = p.breakpoints();
  double worst = 0.0;
  for (size_t k = 0; k < batch.imu.size(); ++k) {
    const double t0 = stream.interval_start_s(), t1 = stream.next_time_s();
    bool straddles = false;
    for (double b : breaks) straddles = straddles || (b > t0 && b < t1);
    const ImuIncrement inc = stream.next([&](double t) { return p.at(t); });
    const double d = (inc.dv_mps - batch.imu[k].dv_mps).norm();
    if (straddles)
      worst = std::max(worst, d);
    else
      ASSERT_LT(d, 1e-13) << k;
  }
  EXPECT_GT(worst, 1e-7);
  EXPECT_LT(worst, 15.0 * kDegToRad * 0.04 * 0.01);
}

TEST(TruthStream, NoisyEqualsBatchSimulatorForTheSameSeed) {
  // The noise generators are the same objects fed in the same order: same seed, same samples.
  const auto p = two_axis_profile();
  UnitModel unit = default_unit();
  unit.noise.gyro_bias_instability_radps = 1e-5;
  unit.noise.accel_bias_instability_mps2 = 1e-4;
  SimOptions o;
  o.seed = 42;
  const SimResult batch = simulate(p, TableGeometry{}, demo_factory_site(), unit, o);
  const ImuSeries s = stream_profile(p, unit, o);
  ASSERT_EQ(s.size(), batch.imu.size());
  const double tol_dth = 2.0 * unit.noise.dtheta_lsb_rad, tol_dv = 2.0 * unit.noise.dv_lsb_mps;
  for (size_t k = 0; k < s.size(); ++k) {
    ASSERT_LE((s[k].dtheta_rad - batch.imu[k].dtheta_rad).lpNorm<Eigen::Infinity>(), tol_dth) << k;
    ASSERT_LE((s[k].dv_mps - batch.imu[k].dv_mps).lpNorm<Eigen::Infinity>(), tol_dv) << k;
  }
}

namespace {

struct Stats {
  double mean = 0.0, var = 0.0, lag1 = 0.0;  // lag-1 autocorrelation coefficient
};

Stats stats_of(const std::vector<double>& x) {
  Stats s;
  for (double v : x) s.mean += v;
  s.mean /= static_cast<double>(x.size());
  double c1 = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    s.var += (x[i] - s.mean) * (x[i] - s.mean);
    if (i > 0) c1 += (x[i] - s.mean) * (x[i - 1] - s.mean);
  }
  s.lag1 = c1 / s.var;
  s.var /= static_cast<double>(x.size() - 1);
  return s;
}

/// Noisy minus noiseless output of the same unit at rest, per axis (the injected noise alone).
std::array<std::array<std::vector<double>, 3>, 2> noise_at_rest(const UnitModel& unit, size_t n) {
  SimOptions on, off;
  on.seed = 9;
  off.noise = false;
  TruthStream noisy(TableGeometry{}, demo_factory_site(), unit, on);
  TruthStream clean(TableGeometry{}, demo_factory_site(), unit, off);
  sequences::TableState rest;
  rest.outer_rad = 0.4;
  rest.inner_rad = -1.1;
  rest.at_rest = true;
  const auto at = [&](double) { return rest; };
  std::array<std::array<std::vector<double>, 3>, 2> r;  // [gyro|accel][axis]
  for (size_t k = 0; k < n; ++k) {
    const ImuIncrement a = noisy.next(at), b = clean.next(at);
    for (int i = 0; i < 3; ++i) {
      r[0][i].push_back(a.dtheta_rad(i) - b.dtheta_rad(i));
      r[1][i].push_back(a.dv_mps(i) - b.dv_mps(i));
    }
  }
  return r;
}

}  // namespace

TEST(TruthStream, WhiteNoiseMatchesArwVrwAndQuantisation) {
  UnitModel unit = default_unit();  // ARW 0.0015 °/√h, VRW 10 µg/√Hz, LSBs 1e-9 rad / 1e-7 m/s
  const size_t n = 40000;
  const double dt = 0.01;
  const auto r = noise_at_rest(unit, n);
  // Per sample: σ² = ARW² dt (white increment) + the carried-quantisation error, the difference of
  // two successive independent uniform remainders: 2 × lsb²/12.
  const double var_g = std::pow(unit.noise.arw_rad_per_sqrt_s, 2) * dt +
                       std::pow(unit.noise.dtheta_lsb_rad, 2) / 6.0;
  const double var_a =
      std::pow(unit.noise.vrw_mps_per_sqrt_s, 2) * dt + std::pow(unit.noise.dv_lsb_mps, 2) / 6.0;
  // Sample variance of n Gaussian values: relative standard error sqrt(2/n) = 0.7 %; allow 5σ.
  const double rel_tol = 5.0 * std::sqrt(2.0 / static_cast<double>(n));
  for (int i = 0; i < 3; ++i) {
    const Stats g = stats_of(r[0][i]), a = stats_of(r[1][i]);
    EXPECT_NEAR(g.var / var_g, 1.0, rel_tol) << "gyro axis " << i;
    EXPECT_NEAR(a.var / var_a, 1.0, rel_tol) << "accel axis " << i;
    EXPECT_LT(std::abs(g.mean), 5.0 * std::sqrt(var_g / static_cast<double>(n))) << i;
    EXPECT_LT(std::abs(a.mean), 5.0 * std::sqrt(var_a / static_cast<double>(n))) << i;
    // White: lag-1 correlation ~ N(0, 1/n), except the quantisation's small negative correlation.
    EXPECT_LT(std::abs(g.lag1), 5.0 / std::sqrt(static_cast<double>(n))) << i;
    EXPECT_LT(std::abs(a.lag1), 5.0 / std::sqrt(static_cast<double>(n))) << i;
  }
}

TEST(TruthStream, GaussMarkovBiasMatchesSigmaAndCorrelationTime) {
  UnitModel unit = default_unit();
  unit.noise.arw_rad_per_sqrt_s = 0.0;
  unit.noise.vrw_mps_per_sqrt_s = 0.0;
  unit.noise.dtheta_lsb_rad = 0.0;
  unit.noise.dv_lsb_mps = 0.0;
  unit.noise.gyro_bias_instability_radps = 2e-4;
  unit.noise.gyro_bias_tau_s = 0.2;
  unit.noise.accel_bias_instability_mps2 = 3e-3;
  unit.noise.accel_bias_tau_s = 0.5;
  const size_t n = 60000;
  const double dt = 0.01;
  const auto r = noise_at_rest(unit, n);
  // The increment error is x_k dt: x is stationary with variance σ² and lag-1 correlation
  // exp(-dt/τ) (eq. 16-17). Pooled over the three axes, the variance estimate of a first-order
  // Markov series has about n dt / (2τ) × 3 independent values.
  struct Case {
    int kind;
    double sigma, tau;
  };
  for (const Case c :
       {Case{0, unit.noise.gyro_bias_instability_radps, unit.noise.gyro_bias_tau_s},
        Case{1, unit.noise.accel_bias_instability_mps2, unit.noise.accel_bias_tau_s}}) {
    double var = 0.0, lag1 = 0.0;
    for (int i = 0; i < 3; ++i) {
      std::vector<double> x = r[c.kind][i];
      for (double& v : x) v /= dt;
      const Stats s = stats_of(x);
      var += s.var / 3.0;
      lag1 += s.lag1 / 3.0;
    }
    const double n_eff = 3.0 * static_cast<double>(n) * dt / (2.0 * c.tau);
    EXPECT_NEAR(var / (c.sigma * c.sigma), 1.0, 5.0 * std::sqrt(2.0 / n_eff)) << c.kind;
    const double phi = std::exp(-dt / c.tau);
    EXPECT_NEAR(lag1, phi, 5.0 * (1.0 - phi * phi) / std::sqrt(3.0 * static_cast<double>(n)) + 2e-3)
        << c.kind;
  }
}

TEST(TruthStream, RefusesWhatItCannotStream) {
  // The table time offset acts on the encoder log only (the caller's), so the stream accepts it.
  UnitModel unit = default_unit();
  unit.effects.table_time_offset_s = 0.002;
  EXPECT_NO_THROW(TruthStream(TableGeometry{}, demo_factory_site(), unit, SimOptions{}));
  SimOptions bad;
  bad.rate_hz = 0.0;
  EXPECT_THROW(TruthStream(TableGeometry{}, demo_factory_site(), default_unit(), bad),
               std::invalid_argument);
  // Breakpoints outside the interval are a caller error, named.
  TruthStream s(TableGeometry{}, demo_factory_site(), unit_with_effects(), SimOptions{});
  sequences::TableState rest;
  try {
    s.next([&](double) { return rest; }, {0.5});
    FAIL() << "breakpoint outside the interval accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("breakpoint"), std::string::npos) << e.what();
  }
}
