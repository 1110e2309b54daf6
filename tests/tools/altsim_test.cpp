// altsim (tools/altsim, issue #22), the independent simulator of the factory table run, against
// the project's truth simulator (calib/sim) and on its own:
//  (a) noise-free increments of the same unit, table, site and sequence agree with the truth
//      simulator's to the two schemes' numerical error — both implement the same physics;
//  (b) every deterministic effect of the catalogue changes the increments (or the encoder log) as
//      it changes the truth simulator's — the conventions (signs, frames, parameter order) match;
//  (c) altsim's noise: its normal generator, the white noise it adds, the Gauss-Markov bias
//      instability (variance, correlation time) and the quantiser's carried remainder;
//  (d) end to end: `altsim` archives that `imucal calibrate` passes and `imucal diagnose` finds
//      consistent, or names a withheld gyro g-sensitivity in.
// The tolerances and why are next to each check; the figures measured are printed.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <future>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "calib/core/site_presets.hpp"
#include "calib/core/table_model.hpp"
#include "calib/effects/catalogue.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/library.hpp"
#include "tests/support/run_command.hpp"
#include "tests/support/temp_dir.hpp"
#include "tools/altsim/alt_kinematics.hpp"
#include "tools/altsim/alt_random.hpp"
#include "tools/altsim/alt_sim.hpp"
#include "tools/imucal/alt_run_source.hpp"

namespace {

using imucal::kArcsecToRad;
using imucal::kDegPerHourToRadPerSec;
using imucal::kStandardGravity_mps2;
namespace calib = imucal::calib;
namespace altsim = imucal::tools::altsim;
namespace sequences = imucal::sequences;

// Numerical agreement of two exact-physics schemes (test a). The truth simulator is exact to
// rounding; altsim's scheme error is far below it: RK4's local error on the quaternion is
// ~(ω h)^5 with ω = 10 °/s, h = 1/800 s (~5e-19 rad per substep), and the ω̇ jumps never fall
// inside a piece; Simpson's error on the dv integrand (smooth at the table's and the Earth's
// rates between breakpoints) is ~h^4 f'''' T / 180 < 1e-20 m/s. What remains is rounding: a
// quaternion of norm 1 carried through 8 RK4 steps holds the ~1.7e-3 rad increment to a few
// 1e-16 absolute, and the truth's log of a product of three attitude matrices as much; dv to a
// few 1e-16 m/s. And one ambiguity of floating-point time: the truth takes dθ between the
// attitudes at k·dt and (k+1)·dt, altsim integrates over [k·dt, k·dt + dt]; the two ends differ
// by up to an ulp of t (1.1e-13 s at the short sequence's 517 s), which at 10 °/s is 2e-14 rad.
// Hence 5e-14 rad and 5e-15 m/s, while a convention error of 1 µrad or 0.1 µg would be 1e-6 rad
// or 1e-8 m/s per sample.
constexpr double kTolDtheta_rad = 5e-14;
constexpr double kTolDv_mps = 5e-15;

const sequences::MotionProfile& short_profile() {
  static const sequences::MotionProfile p = sequences::load_profile("short");
  return p;
}

calib::effects::RunSource truth_source() {
  return calib::sim::truth_run_source(short_profile(), calib::core::TableGeometry{},
                                      calib::core::demo_factory_site(),
                                      calib::effects::default_unit(), 100.0);
}
calib::effects::RunSource alt_source() {
  return imucal::tools::imucal::alt_run_source(short_profile(), calib::core::TableGeometry{},
                                               calib::core::demo_factory_site(),
                                               calib::effects::default_unit(), 100.0);
}

/// Largest per-sample difference of the increments of two runs (same length and times).
struct IncrementDiff {
  double dtheta_rad = 0.0, dv_mps = 0.0;
};
IncrementDiff max_diff(const calib::core::CalibrationInput& a,
                       const calib::core::CalibrationInput& b) {
  IncrementDiff d;
  for (size_t k = 0; k < a.imu.size(); ++k) {
    d.dtheta_rad = std::max(d.dtheta_rad, (a.imu[k].dtheta_rad - b.imu[k].dtheta_rad).norm());
    d.dv_mps = std::max(d.dv_mps, (a.imu[k].dv_mps - b.imu[k].dv_mps).norm());
  }
  return d;
}

TEST(AltSim, NoiseFreeIncrementsAgreeWithTheTruthSimulator) {
  const calib::core::CalibrationInput truth = truth_source()(calib::effects::Effects{}, 1, false);
  const calib::core::CalibrationInput alt = alt_source()(calib::effects::Effects{}, 1, false);
  ASSERT_EQ(alt.imu.size(), truth.imu.size());
  ASSERT_EQ(alt.reference.size(), truth.reference.size());
  double max_rate_radps = 0.0;
  for (size_t k = 0; k < alt.imu.size(); ++k) {
    ASSERT_NEAR(alt.imu[k].t_s, truth.imu[k].t_s, 1e-12) << k;
    ASSERT_DOUBLE_EQ(alt.imu[k].dt_s, truth.imu[k].dt_s) << k;
    // The encoder log and the rest flags are the same (the degrees round-trip to ~1 ulp).
    ASSERT_EQ(alt.reference[k].at_rest, truth.reference[k].at_rest) << k;
    ASSERT_NEAR(alt.reference[k].outer_rad, truth.reference[k].outer_rad, 1e-14) << k;
    ASSERT_NEAR(alt.reference[k].inner_rad, truth.reference[k].inner_rad, 1e-14) << k;
    ASSERT_LT((alt.reference[k].C_bn_ref - truth.reference[k].C_bn_ref).norm(), 1e-14) << k;
    max_rate_radps = std::max(max_rate_radps, truth.imu[k].dtheta_rad.norm() / truth.imu[k].dt_s);
  }
  const IncrementDiff d = max_diff(alt, truth);
  std::printf(
      "noise-free altsim - truth over %zu samples (table up to %.1f deg/s): max |d dtheta| "
      "%.3g rad, max |d dv| %.3g m/s\n",
      alt.imu.size(), max_rate_radps / imucal::kDegToRad, d.dtheta_rad, d.dv_mps);
  EXPECT_GT(max_rate_radps, 9.0 * imucal::kDegToRad);  // the comparison covered the rotations
  EXPECT_LT(d.dtheta_rad, kTolDtheta_rad);
  EXPECT_LT(d.dv_mps, kTolDv_mps);
  EXPECT_EQ(alt.noise.arw_rad_per_sqrt_s, calib::effects::default_unit().noise.arw_rad_per_sqrt_s);
  EXPECT_EQ(alt.site.lat_rad, calib::core::demo_factory_site().lat_rad);
}

TEST(AltSim, RunSourceIsCallableFromSeveralThreadsAtOnce) {
  const calib::effects::RunSource src = alt_source();
  calib::effects::Effects fx;
  fx.gyro_accel_skew_s = 1e-3;
  auto job = [&src, &fx](uint64_t seed) { return src(fx, seed, true); };
  auto a = std::async(std::launch::async, job, 5);
  auto b = std::async(std::launch::async, job, 6);
  const calib::core::CalibrationInput ra = a.get(), rb = b.get();
  const IncrementDiff same_a = max_diff(ra, src(fx, 5, true));
  EXPECT_EQ(same_a.dtheta_rad, 0.0);  // deterministic per seed, undisturbed by the other thread
  EXPECT_EQ(same_a.dv_mps, 0.0);
  EXPECT_GT(max_diff(ra, rb).dtheta_rad, 0.0);  // different seeds, different noise
}

/// An effect set at `factor` times the catalogue's typical value (shape parameters kept).
calib::effects::Effects scaled_typical(calib::effects::EffectId id, double factor) {
  const calib::effects::EffectInfo& e = calib::effects::effect_info(id);
  Eigen::VectorXd v(e.size());
  for (int i = 0; i < e.size(); ++i) {
    const auto u = static_cast<size_t>(i);
    v(i) = e.params[u].shape ? e.typical[u] : factor * e.typical[u];
  }
  calib::effects::Effects fx;
  calib::effects::set_effect_vector(fx, id, v);
  return fx;
}

// (b) Each effect's change of the increments, altsim's against the truth's, at 10x the
// catalogue's typical size. Table and site effects change the physics both schemes integrate
// exactly: they agree to the rounding of (a) plus 1e-9 of the change. The sensor effects: the
// truth evaluates them once per sample at the interval's mean force and rate (dv/dt, dθ/dt),
// altsim at every substep node on the force and rate expressed in the interval's start frame, and
// Simpson-integrates; in that frame gravity only turns with the Earth within a sample, so the two
// differ at second order (the within-sample spread, e.g. |f| against |mean f|): 1e-6 of the
// change. The size effect differs by more, on purpose: altsim differentiates the rate w.r.t.
// inertial space (ω̇_ib = ω̇_nb - ω_nb × ω_ie_b), the truth uses the table's ω̇_nb; the term is
// 10 °/s × 7.3e-5 rad/s = 1.3e-5 rad/s² against the ramps' 0.17 rad/s², 7e-5 of the change:
// 2e-4. A wrong sign, axis, frame or transposition is an error of order 1 of the change.
struct EffectCase {
  calib::effects::EffectId id;
  double rel_tol;
};

TEST(AltSim, EveryDeterministicEffectChangesTheIncrementsAsInTheTruthSimulator) {
  const calib::effects::RunSource truth = truth_source(), alt = alt_source();
  const calib::core::CalibrationInput truth0 = truth(calib::effects::Effects{}, 1, false);
  const calib::core::CalibrationInput alt0 = alt(calib::effects::Effects{}, 1, false);
  using Id = calib::effects::EffectId;
  const std::vector<EffectCase> cases = {
      {Id::kAccelQuadraticK2, 1e-6},      {Id::kAccelAsymmetry, 1e-6}, {Id::kSizeEffect, 2e-4},
      {Id::kGyroGSensitivity, 1e-6},      {Id::kGyroAccelSkew, 1e-6},  {Id::kThermalDrift, 1e-6},
      {Id::kTableNonorthogonality, 1e-9}, {Id::kTableWobble, 1e-9},    {Id::kGravityError, 1e-9},
      {Id::kLatitudeError, 1e-9}};
  for (const EffectCase& c : cases) {
    const std::string name = calib::effects::effect_info(c.id).name;
    const calib::effects::Effects fx = scaled_typical(c.id, 10.0);
    const calib::core::CalibrationInput t1 = truth(fx, 1, false), a1 = alt(fx, 1, false);
    double scale_th = 0.0, scale_dv = 0.0, err_th = 0.0, err_dv = 0.0;
    for (size_t k = 0; k < t1.imu.size(); ++k) {
      const Eigen::Vector3d dt_th = t1.imu[k].dtheta_rad - truth0.imu[k].dtheta_rad;
      const Eigen::Vector3d dt_dv = t1.imu[k].dv_mps - truth0.imu[k].dv_mps;
      const Eigen::Vector3d da_th = a1.imu[k].dtheta_rad - alt0.imu[k].dtheta_rad;
      const Eigen::Vector3d da_dv = a1.imu[k].dv_mps - alt0.imu[k].dv_mps;
      scale_th = std::max(scale_th, dt_th.norm());
      scale_dv = std::max(scale_dv, dt_dv.norm());
      err_th = std::max(err_th, (da_th - dt_th).norm());
      err_dv = std::max(err_dv, (da_dv - dt_dv).norm());
    }
    std::printf(
        "%-24s change max |dtheta| %9.3g rad, |dv| %9.3g m/s; altsim - truth: %9.3g rad "
        "(%.2g of it), %9.3g m/s (%.2g of it)\n",
        name.c_str(), scale_th, scale_dv, err_th, scale_th > 0 ? err_th / scale_th : 0.0, err_dv,
        scale_dv > 0 ? err_dv / scale_dv : 0.0);
    EXPECT_GT(std::max(scale_th / kTolDtheta_rad, scale_dv / kTolDv_mps), 1e3)
        << name << ": the effect must change the increments well above the rounding";
    EXPECT_LE(err_th, 2.0 * kTolDtheta_rad + c.rel_tol * scale_th) << name;
    EXPECT_LE(err_dv, 2.0 * kTolDv_mps + c.rel_tol * scale_dv) << name;
  }
}

// The output filter (a lag, so it acts without noise too) smooths the increments as in the truth
// simulator: altsim's exponential smoother and calib/sim's recursive filter are the same
// y_k = a y_{k-1} + (1-a) x_k written two ways, and the change it makes is well above the rounding.
TEST(AltSim, OutputFilterSmoothsTheIncrementsAsInTheTruthSimulator) {
  const calib::effects::RunSource truth = truth_source(), alt = alt_source();
  calib::effects::Effects fx;
  fx.output_filter_gyro = 0.6;
  fx.output_filter_accel = 0.3;
  const calib::core::CalibrationInput t0 = truth(calib::effects::Effects{}, 1, false);
  const calib::core::CalibrationInput t1 = truth(fx, 1, false), a1 = alt(fx, 1, false);
  double change_th = 0.0, change_dv = 0.0, err_th = 0.0, err_dv = 0.0;
  for (size_t k = 0; k < t1.imu.size(); ++k) {
    change_th = std::max(change_th, (t1.imu[k].dtheta_rad - t0.imu[k].dtheta_rad).norm());
    change_dv = std::max(change_dv, (t1.imu[k].dv_mps - t0.imu[k].dv_mps).norm());
    err_th = std::max(err_th, (a1.imu[k].dtheta_rad - t1.imu[k].dtheta_rad).norm());
    err_dv = std::max(err_dv, (a1.imu[k].dv_mps - t1.imu[k].dv_mps).norm());
  }
  std::printf(
      "output_filter change max |dtheta| %.3g rad, |dv| %.3g m/s; altsim - truth %.3g, %.3g\n",
      change_th, change_dv, err_th, err_dv);
  EXPECT_GT(change_th, 1e3 * kTolDtheta_rad);
  EXPECT_GT(change_dv, 1e3 * kTolDv_mps);
  EXPECT_LE(err_th, 2.0 * kTolDtheta_rad + 1e-6 * change_th);
  EXPECT_LE(err_dv, 2.0 * kTolDv_mps + 1e-6 * change_dv);
}

/// A hand's motion in a run's table rests, as the increments' change from the same run without it
/// shows it: the RMS rate per axis, the slope of the accelerometers' change on gravity turned by
/// the gyro-integrated tilt (f̄ × θ, 0.2 s block means: the tremor and the pivot's shake average
/// out), and the RMS of what the tilt leaves of the accelerometers' change (the pivot's force).
struct HandStats {
  double rate_rms_radps = 0.0, slope = 0.0, pivot_rms_mps2 = 0.0;
};

HandStats hand_stats(const calib::core::CalibrationInput& with,
                     const calib::core::CalibrationInput& without) {
  constexpr size_t kBlock = 20;
  double w2 = 0.0, sxy = 0.0, sxx = 0.0, p2 = 0.0;
  size_t n = 0;
  for (size_t k = 0; k < with.imu.size();) {
    if (!with.reference[k].at_rest) {
      ++k;
      continue;
    }
    size_t e = k;
    while (e < with.imu.size() && with.reference[e].at_rest) ++e;
    // Per sample of the rest: the hand's turn since the rest's flagged start and the force's
    // change; then each less its mean over the rest (the turn before the flag is unknown here).
    const size_t m = e - k;
    std::vector<Eigen::Vector3d> theta(m), df(m);
    Eigen::Vector3d f_mean = Eigen::Vector3d::Zero(), th = Eigen::Vector3d::Zero();
    Eigen::Vector3d th_mean = Eigen::Vector3d::Zero(), df_mean = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < m; ++i) {
      const calib::core::ImuIncrement &a = with.imu[k + i], &b = without.imu[k + i];
      f_mean += b.dv_mps / b.dt_s / m;
      w2 += ((a.dtheta_rad - b.dtheta_rad) / a.dt_s).squaredNorm() / 3.0;
      ++n;
      th += a.dtheta_rad - b.dtheta_rad;
      theta[i] = th;
      df[i] = (a.dv_mps - b.dv_mps) / a.dt_s;
      th_mean += th / m;
      df_mean += df[i] / m;
    }
    for (size_t b = 0; b + kBlock <= m; b += kBlock) {
      Eigen::Vector3d x = Eigen::Vector3d::Zero(), y = Eigen::Vector3d::Zero();
      for (size_t i = b; i < b + kBlock; ++i) {
        const Eigen::Vector3d xi = f_mean.cross(theta[i] - th_mean), yi = df[i] - df_mean;
        p2 += (yi - xi).squaredNorm();
        x += xi / kBlock;
        y += yi / kBlock;
      }
      sxy += x.dot(y);
      sxx += x.squaredNorm();
    }
    k = e;
  }
  HandStats h;
  h.rate_rms_radps = std::sqrt(w2 / std::max<size_t>(1, n));
  h.slope = sxx > 0.0 ? sxy / sxx : 0.0;
  h.pivot_rms_mps2 = std::sqrt(p2 / std::max<size_t>(1, n));
  return h;
}

// rest_tremor (a hand holding the unit in the table's rests): altsim draws its own hand from its
// own generator, so the two simulators' increments differ sample by sample; what they share is the
// effect's definition. Noise-free, against each one's own run without the hand: the RMS rate in
// the rests agrees (the tremor's 0.5 °/s and the sway's rate, ~0.3 °/s at 0.05°; each run draws
// 3 + 2 frequencies per axis for each of short's 19 rests: ±10 %), the accelerometers follow the
// gyro-integrated tilt with slope 1 in both (a sign or frame slip would give -1 or nothing; the
// pivot's force on 0.2 s blocks moves it by ±0.2), and the pivot's force has one size (±25 %).
TEST(AltSim, RestTremorTurnsTheUnitInTheRestsAsInTheTruthSimulator) {
  const calib::effects::RunSource truth = truth_source(), alt = alt_source();
  calib::effects::Effects fx;
  fx.tremor_rate_rms_radps = 0.5 * imucal::kDegToRad;
  fx.tremor_tilt_rms_rad = 0.05 * imucal::kDegToRad;
  fx.tremor_pivot_m = 0.1;
  const HandStats t = hand_stats(truth(fx, 1, false), truth(calib::effects::Effects{}, 1, false));
  const HandStats a = hand_stats(alt(fx, 1, false), alt(calib::effects::Effects{}, 1, false));
  for (const auto& [who, h] : {std::pair{"truth", t}, std::pair{"altsim", a}})
    std::printf("rest_tremor %s: rate RMS %.3f deg/s, slope %.3f, pivot force RMS %.2f mg\n", who,
                h.rate_rms_radps * imucal::kRadToDeg, h.slope,
                h.pivot_rms_mps2 / kStandardGravity_mps2 * 1e3);
  EXPECT_GT(t.rate_rms_radps, fx.tremor_rate_rms_radps);
  EXPECT_NEAR(a.rate_rms_radps / t.rate_rms_radps, 1.0, 0.1);
  EXPECT_NEAR(t.slope, 1.0, 0.2);
  EXPECT_NEAR(a.slope, 1.0, 0.2);
  EXPECT_NEAR(a.pivot_rms_mps2 / t.pivot_rms_mps2, 1.0, 0.25);
}

TEST(AltSim, TableTimeOffsetDelaysTheEncoderLogAsInTheTruthSimulator) {
  const calib::effects::RunSource truth = truth_source(), alt = alt_source();
  calib::effects::Effects fx;
  fx.table_time_offset_s = 0.005;
  const calib::core::CalibrationInput t0 = truth(calib::effects::Effects{}, 1, false),
                                      t1 = truth(fx, 1, false);
  const calib::core::CalibrationInput a0 = alt(calib::effects::Effects{}, 1, false),
                                      a1 = alt(fx, 1, false);
  double scale = 0.0, err = 0.0;
  for (size_t k = 0; k < t1.reference.size(); ++k) {
    const double dt_o = t1.reference[k].outer_rad - t0.reference[k].outer_rad;
    const double dt_i = t1.reference[k].inner_rad - t0.reference[k].inner_rad;
    const double da_o = a1.reference[k].outer_rad - a0.reference[k].outer_rad;
    const double da_i = a1.reference[k].inner_rad - a0.reference[k].inner_rad;
    scale = std::max({scale, std::abs(dt_o), std::abs(dt_i)});
    err = std::max({err, std::abs(da_o - dt_o), std::abs(da_i - dt_i)});
  }
  std::printf("table_time_offset 5 ms: encoder change up to %.3g rad, altsim - truth %.3g rad\n",
              scale, err);
  // 10 °/s × 5 ms; both read the same profile at t - offset, up to the degree round trip.
  EXPECT_NEAR(scale, 10.0 * imucal::kDegToRad * 0.005, 1e-6);
  EXPECT_LT(err, 1e-14);
  EXPECT_LT(max_diff(a1, a0).dtheta_rad, 1e-18);  // the unit's increments do not change
}

// The table kinematics alone: the body rate altsim derives from the gimbal rates is the
// attitude's derivative, and its angular acceleration the rate's, with the table's imperfections
// exaggerated (1-2 mrad) so that their rate terms would show (the wobble's own rate is ~1e-3
// rad/s here, its second-order part ½|δ||δ̇| ~ 1e-6 rad/s). Central differences over ±1e-5 s
// are exact to ~ε²|ω|³/6 ≈ 1e-10 at the 1.8 rad/s the segment reaches and round to ~1e-16/ε.
TEST(AltSim, GimbalRatesAreTheDerivativeOfTheAttitude) {
  altsim::AltTable table;
  table.misalignment_rad = Eigen::Vector3d(1e-4, -2e-4, 3e-4);
  altsim::AltEffects fx;
  fx.table_nonorthogonality_rad = 1e-3;
  fx.table_wobble_rad = Eigen::Vector2d(1e-3, -2e-3);
  const altsim::TableKinematics kin(table, fx, 0.97, 9.81, 0.0);  // no Earth rate: ω_ib = ω_nb
  sequences::ProfileSegment seg;
  seg.t0_s = 0.0;
  seg.t1_s = 10.0;
  seg.outer = {0.3, 0.2, 0.15};
  seg.inner = {-1.1, -0.25, 0.2};
  const double eps = 1e-5;
  for (double t : {0.5, 3.0, 7.25}) {
    const altsim::BodyKinematics k = kin.at(altsim::state_in_segment(seg, t), true);
    const auto C = [&](double s) {
      const sequences::TableState st = altsim::state_in_segment(seg, s);
      return kin.C_bn(st.outer_rad, st.inner_rad);
    };
    const Eigen::Matrix3d Cdot_b = k.C_bn.transpose() * (C(t + eps) - C(t - eps)) / (2 * eps);
    const Eigen::Vector3d w_fd(Cdot_b(2, 1), Cdot_b(0, 2), Cdot_b(1, 0));
    EXPECT_LT((k.C_bn - C(t)).norm(), 1e-15);
    EXPECT_LT((w_fd - k.w_ib_b).norm(), 1e-9) << "t " << t;
    const Eigen::Vector3d wdot_fd = (kin.at(altsim::state_in_segment(seg, t + eps), false).w_ib_b -
                                     kin.at(altsim::state_in_segment(seg, t - eps), false).w_ib_b) /
                                    (2 * eps);
    EXPECT_LT((wdot_fd - k.wdot_ib_b).norm(), 1e-9) << "t " << t;
  }
}

// (c) The normal generator: mean, variance, lag-1 autocorrelation and kurtosis of 2e6 deviates,
// each within 5 standard errors (sd of the mean 1/√N, of the variance √(2/N), of r1 1/√N, of the
// fourth moment √(96/N)): a failure is a 1-in-10^6 event for a correct generator.
TEST(AltSim, PolarNormalsHaveUnitVarianceAndNoLag1Correlation) {
  altsim::PolarNormal normal(12345);
  const int n = 2000000;
  std::vector<double> x(n);
  for (double& v : x) v = normal();
  double m = 0.0;
  for (double v : x) m += v;
  m /= n;
  double m2 = 0.0, m4 = 0.0, c1 = 0.0;
  for (int i = 0; i < n; ++i) {
    const double d = x[i] - m;
    m2 += d * d;
    m4 += d * d * d * d;
    if (i > 0) c1 += d * (x[i - 1] - m);
  }
  m2 /= n;
  m4 /= n;
  const double r1 = c1 / (n * m2);
  std::printf("polar normals: mean %.2e, variance %.5f, lag-1 r %.2e, kurtosis %.4f (N %d)\n", m,
              m2, r1, m4 / (m2 * m2), n);
  EXPECT_LT(std::abs(m), 5.0 / std::sqrt(n));
  EXPECT_LT(std::abs(m2 - 1.0), 5.0 * std::sqrt(2.0 / n));
  EXPECT_LT(std::abs(r1), 5.0 / std::sqrt(n));
  EXPECT_LT(std::abs(m4 - 3.0), 5.0 * std::sqrt(96.0 / n));
  // Different seeds give different streams (splitmix64 spreads neighbouring seeds).
  altsim::PolarNormal other(12346);
  EXPECT_NE(other(), altsim::PolarNormal(12345)());
}

/// The noise altsim adds to a run of `profile`: its output with noise minus without.
std::vector<altsim::AltSample> noise_only(const sequences::MotionProfile& profile,
                                          const altsim::AltUnit& unit, double rate_hz) {
  altsim::AltOptions o;
  o.rate_hz = rate_hz;
  o.seed = 77;
  o.noise = true;
  std::vector<altsim::AltSample> with =
      altsim::simulate_alt(profile, altsim::AltTable{}, altsim::AltSite{}, unit, o);
  o.noise = false;
  const std::vector<altsim::AltSample> without =
      altsim::simulate_alt(profile, altsim::AltTable{}, altsim::AltSite{}, unit, o);
  for (size_t k = 0; k < with.size(); ++k) {
    with[k].dtheta_rad -= without[k].dtheta_rad;
    with[k].dv_mps -= without[k].dv_mps;
  }
  return with;
}

/// Mean, variance and lag-L autocorrelation of one axis of the noise.
struct SeriesStats {
  double mean = 0.0, var = 0.0, r_lag = 0.0;
};
SeriesStats series_stats(const std::vector<double>& x, size_t lag) {
  SeriesStats s;
  for (double v : x) s.mean += v;
  s.mean /= static_cast<double>(x.size());
  double c = 0.0;
  for (size_t i = 0; i < x.size(); ++i) {
    s.var += (x[i] - s.mean) * (x[i] - s.mean);
    if (i >= lag) c += (x[i] - s.mean) * (x[i - lag] - s.mean);
  }
  s.r_lag = c / s.var;
  s.var /= static_cast<double>(x.size());
  return s;
}

std::vector<double> axis(const std::vector<altsim::AltSample>& run, bool gyro, int i,
                         double scale) {
  std::vector<double> x;
  x.reserve(run.size());
  for (const auto& s : run) x.push_back((gyro ? s.dtheta_rad(i) : s.dv_mps(i)) * scale);
  return x;
}

// White noise in a simulated run (the short sequence, 51 700 samples per axis): per axis the sd
// within 5 standard errors (√(1/(2N)) relative, 1.6 %) of ARW·√dt and VRW·√dt, mean and lag-1
// autocorrelation within 5/√N.
TEST(AltSim, WhiteNoiseHasTheDeclaredSpreadAndIsWhite) {
  altsim::AltUnit unit;
  unit.noise.arw_rad_per_sqrt_s = 0.0015 * imucal::kDegToRad / 60.0;
  unit.noise.vrw_mps_per_sqrt_s = 10.0 * imucal::kMicroG_mps2;
  const std::vector<altsim::AltSample> run = noise_only(short_profile(), unit, 100.0);
  const double n = static_cast<double>(run.size());
  for (bool gyro : {true, false})
    for (int i = 0; i < 3; ++i) {
      const double sd =
          (gyro ? unit.noise.arw_rad_per_sqrt_s : unit.noise.vrw_mps_per_sqrt_s) * std::sqrt(0.01);
      const SeriesStats s = series_stats(axis(run, gyro, i, 1.0 / sd), 1);
      std::printf("white %s %c: mean %+.4f sd, sd ratio %.4f, lag-1 r %+.4f\n",
                  gyro ? "gyro " : "accel", "xyz"[i], s.mean, std::sqrt(s.var), s.r_lag);
      EXPECT_LT(std::abs(s.mean), 5.0 / std::sqrt(n));
      EXPECT_LT(std::abs(std::sqrt(s.var) - 1.0), 5.0 * std::sqrt(1.0 / (2.0 * n)));
      EXPECT_LT(std::abs(s.r_lag), 5.0 / std::sqrt(n));
    }
}

// The bias_instability effect alone on a 400 000 s rest at 1 Hz, τ = 20 s: the noise is x_k dt.
// Over T/τ = 20 000 correlation times the stationary variance is known to ~√(2τ/T) = 1 % per
// axis and the lag-1 correlation φ = exp(-dt/τ) to √((1-φ²)/N) ≈ 4.9e-4, i.e. τ to ~1 % per axis;
// pooled over six axes, 5 standard errors are ~2.1 % for the variance and ~2.1 % for τ. The
// correlation at a lag of τ must be e^-1.
TEST(AltSim, GaussMarkovBiasHasItsSigmaAndCorrelationTime) {
  sequences::MotionProfile rest;
  rest.name = "rest";
  sequences::ProfileSegment seg;
  seg.t1_s = 400000.0;
  rest.segments.push_back(seg);
  altsim::AltUnit unit;
  unit.effects.instability_gyro_radps = 1e-6;
  unit.effects.instability_accel_mps2 = 1e-4;
  unit.effects.instability_tau_s = 20.0;
  const std::vector<altsim::AltSample> run = noise_only(rest, unit, 1.0);
  double var_ratio = 0.0, phi = 0.0, r_tau = 0.0;
  for (bool gyro : {true, false})
    for (int i = 0; i < 3; ++i) {
      const double sigma = gyro ? 1e-6 : 1e-4;
      const std::vector<double> x = axis(run, gyro, i, 1.0 / sigma);  // dt = 1 s
      var_ratio += series_stats(x, 1).var / 6.0;
      phi += series_stats(x, 1).r_lag / 6.0;
      r_tau += series_stats(x, 20).r_lag / 6.0;
    }
  const double tau_est_s = -1.0 / std::log(phi);
  std::printf("Gauss-Markov: variance / sigma^2 %.4f, tau %.3f s (20), r(tau) %.4f (%.4f)\n",
              var_ratio, tau_est_s, r_tau, std::exp(-1.0));
  EXPECT_NEAR(var_ratio, 1.0, 0.021 * 1.5);  // 5 standard errors plus the finite-T mean removal
  EXPECT_NEAR(tau_est_s, 20.0, 20.0 * 0.021);
  EXPECT_NEAR(r_tau, std::exp(-1.0), 0.02);
}

// The quantisation effect: every output a whole number of LSBs, and the remainder carried: the
// running sum of the quantised output never departs from the unquantised one by more than half
// an LSB (no drift from rounding).
TEST(AltSim, QuantisationCarriesTheRemainder) {
  altsim::AltUnit unit;
  unit.noise.arw_rad_per_sqrt_s = 0.0015 * imucal::kDegToRad / 60.0;
  unit.noise.vrw_mps_per_sqrt_s = 10.0 * imucal::kMicroG_mps2;
  altsim::AltOptions o;
  o.seed = 3;
  altsim::AltSite site;
  site.lat_rad = 0.97;
  const auto plain = altsim::simulate_alt(short_profile(), altsim::AltTable{}, site, unit, o);
  unit.effects.quant_dtheta_rad = 1e-6;
  unit.effects.quant_dv_mps = 1e-4;
  const auto quant = altsim::simulate_alt(short_profile(), altsim::AltTable{}, site, unit, o);
  Eigen::Vector3d sum_th = Eigen::Vector3d::Zero(), sum_dv = Eigen::Vector3d::Zero();
  double worst_th = 0.0, worst_dv = 0.0, off_grid = 0.0;
  for (size_t k = 0; k < quant.size(); ++k) {
    sum_th += quant[k].dtheta_rad - plain[k].dtheta_rad;
    sum_dv += quant[k].dv_mps - plain[k].dv_mps;
    worst_th = std::max(worst_th, sum_th.cwiseAbs().maxCoeff());
    worst_dv = std::max(worst_dv, sum_dv.cwiseAbs().maxCoeff());
    for (int i = 0; i < 3; ++i) {
      const double q = quant[k].dtheta_rad(i) / 1e-6;
      off_grid = std::max(off_grid, std::abs(q - std::round(q)));
    }
  }
  std::printf("quantisation: running-sum departure %.3f / %.3f LSB (dtheta / dv)\n",
              worst_th / 1e-6, worst_dv / 1e-4);
  EXPECT_LT(off_grid, 1e-6);
  EXPECT_LE(worst_th, 0.5e-6 * (1 + 1e-9));
  EXPECT_LE(worst_dv, 0.5e-4 * (1 + 1e-9));
}

// (d) End to end through the programs.
std::string bin(const std::string& name) { return std::string(IMUCAL_BIN_DIR) + "/" + name; }

nlohmann::json diagnose(const std::string& dir) {
  const auto r =
      imucal::test_support::run_command(bin("imucal") + " diagnose " + dir + " --json 2>/dev/null");
  EXPECT_EQ(r.code, 0) << r.out.substr(0, 2000);
  return nlohmann::json::parse(r.out);
}

TEST(AltSimProgram, NullArchiveCalibratesAndIsConsistent) {
  const imucal::test_support::ScopedTempDir tmp("altsim-null");
  const std::string dir = tmp.sub("run");
  const auto sim =
      imucal::test_support::run_command(bin("altsim") + " --sequence short --seed 11 --out " + dir);
  ASSERT_EQ(sim.code, 0) << sim.out;
  const auto cal = imucal::test_support::run_command(bin("imucal") + " calibrate " + dir);
  EXPECT_EQ(cal.code, 0) << cal.out;
  EXPECT_NE(cal.out.find("verdict: PASS"), std::string::npos) << cal.out;
  const nlohmann::json j = diagnose(dir);
  EXPECT_EQ(j["verdict"], "consistent") << j["summary"];
}

TEST(AltSimProgram, WithheldGyroGSensitivityIsNamed) {
  const imucal::test_support::ScopedTempDir tmp("altsim-gsens");
  const std::string dir = tmp.sub("run");
  // Diagonal 0.12, -0.10, 0.11 °/h/g: ~5x the short sequence's detection threshold
  // (`imucal crlb --sequence short --effects`: 0.04 °/h/g).
  const double k = kDegPerHourToRadPerSec / kStandardGravity_mps2;
  const Eigen::Vector3d g_dph_per_g(0.12, -0.10, 0.11);
  char spec[256];
  std::snprintf(spec, sizeof spec, "gyro_g_sensitivity=%.17g,0,0,0,%.17g,0,0,0,%.17g",
                g_dph_per_g(0) * k, g_dph_per_g(1) * k, g_dph_per_g(2) * k);
  const auto sim = imucal::test_support::run_command(
      bin("altsim") + " --sequence short --seed 12 --out " + dir + " --effect " + spec);
  ASSERT_EQ(sim.code, 0) << sim.out;
  const nlohmann::json j = diagnose(dir);
  EXPECT_EQ(j["verdict"], "explained") << j["summary"];
  ASSERT_TRUE(j["best"].is_object()) << j["summary"];
  EXPECT_EQ(j["best"]["effect"], "gyro_g_sensitivity") << j["summary"];
  const char* names[3] = {"G_xx", "G_yy", "G_zz"};
  for (int i = 0; i < 3; ++i)
    for (const auto& p : j["best"]["parameters"]) {
      if (p["name"] != names[i]) continue;
      EXPECT_NEAR(p["value"].get<double>(), g_dph_per_g(i), 4.0 * p["sigma"].get<double>())
          << names[i];
    }
}

TEST(AltSimProgram, BadEffectIsRefusedNamingItsParameters) {
  const imucal::test_support::ScopedTempDir tmp("altsim-bad");
  const auto r = imucal::test_support::run_command(bin("altsim") + " --sequence short --out " +
                                                   tmp.sub("run") +
                                                   " --effect gyro_accel_skew=1e-3,2e-3 2>&1");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("t_GA"), std::string::npos) << r.out;
}

}  // namespace
