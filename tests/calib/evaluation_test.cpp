// The evaluation (paper §VII) is checked against what physics predicts for known parameter
// errors injected into the compensation, on a noisy simulation of a full-rank table sequence:
// noise floors from the VRW/ARW spectra, bias and scale-factor errors from the rest geometry and
// the rotations the table made, and a heading offset from the definition of eq. 51.
#include "calib/checks/evaluation.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "calib/core/rotation.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/library.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

namespace {

Site factory_site() { return demo_factory_site(); }

UnitModel test_unit() {
  UnitModel u = default_unit();  // biases, scale factors, misalignments and a table ς
  u.noise = NoiseModel{};        // ARW 0.0015 °/√h, VRW 10 µg/√Hz, no bias instability
  u.noise.gyro_bias_instability_radps = 0.0;
  u.noise.accel_bias_instability_mps2 = 0.0;
  return u;
}

struct SimRun {
  sequences::MotionProfile profile;
  UnitModel unit;
  CalibrationInput input;
  EvaluationMetrics truth_metrics;  // evaluation with the true parameters
};

// One simulation shared by all tests (the simulator is the expensive part).
const SimRun& shared_run() {
  static const SimRun r = [] {
    SimRun x;
    // The library's short sequence: ±90°/180° rotations about both table axes, body x, y, z
    // up and down, 25-30 s rests.
    x.profile = sequences::load_profile("short");
    x.unit = test_unit();
    SimOptions so;
    so.seed = 7;
    const TableGeometry geom;
    const SimResult sim = simulate(x.profile, geom, factory_site(), x.unit, so);
    x.input = input_from_simulation(sim, geom, factory_site(), x.unit.noise);
    x.truth_metrics = evaluate(x.input, sim.truth);
    return x;
  }();
  return r;
}

/// True attitude of a sample (reference corrected by the true ς).
Eigen::Matrix3d true_C_bn_at(const SimRun& r, size_t k) {
  return rotvec_to_matrix<double>(r.unit.params.table_misalignment_rad) *
         r.input.reference[k].C_bn_ref;
}

double vrw_mps_per_sqrt_s(const SimRun& r) { return r.unit.noise.vrw_mps_per_sqrt_s; }

/// RMS over rest periods of the magnitude of the per-period mean of white VRW noise:
/// each axis has σ = VRW / sqrt(T), so E|mean|² = 3 VRW² / T.
double accel_noise_floor_ug(const SimRun& r) {
  const auto periods = find_rest_periods(r.input, EvaluationOptions{}.min_rest_samples);
  double s = 0.0;
  for (const auto& p : periods) {
    const double T = r.input.imu[p.end - 1].t_s - r.input.imu[p.begin].t_s;
    s += 3.0 * vrw_mps_per_sqrt_s(r) * vrw_mps_per_sqrt_s(r) / T;
  }
  return std::sqrt(s / static_cast<double>(periods.size())) / kMicroG_mps2;
}

/// Orientation floor: the heading random walk of ARW over the run (what remains after the
/// constant offset is fitted is below ARW·sqrt(T_run)) plus the levelling noise of a ZUPT over
/// one (25 s) rest, VRW / (g sqrt(T_rest)).
double orientation_noise_floor_mdeg(const SimRun& r) {
  const double T_run = r.input.imu.back().t_s - r.input.imu.front().t_s;
  const double heading = r.unit.noise.arw_rad_per_sqrt_s * std::sqrt(T_run);
  const double tilt = vrw_mps_per_sqrt_s(r) / (9.8 * std::sqrt(25.0));
  return (heading + tilt) * kRadToDeg * 1e3;
}

}  // namespace

TEST(Evaluation, TrueParametersGiveTheNoiseFloor) {
  const SimRun& r = shared_run();
  const EvaluationMetrics& m = r.truth_metrics;
  const double accel_floor = accel_noise_floor_ug(r);
  const double orient_floor = orientation_noise_floor_mdeg(r);
  std::printf(
      "accel RMSE %.3f µg (white-noise floor %.3f µg); orientation RMSE %.4f mdeg "
      "(floor bound %.4f mdeg); γ_np %.4f mdeg; θ_bp (%.4f %.4f %.4f) mdeg\n",
      m.accel_rmse_ug, accel_floor, m.orientation_rmse_mdeg, orient_floor,
      m.heading_offset_gamma_np_rad * kRadToDeg * 1e3,
      m.body_misalignment_theta_bp_rad(0) * kRadToDeg * 1e3,
      m.body_misalignment_theta_bp_rad(1) * kRadToDeg * 1e3,
      m.body_misalignment_theta_bp_rad(2) * kRadToDeg * 1e3);
  size_t rests = 0;  // every rest segment of the profile is long enough to be evaluated
  for (const auto& seg : r.profile.segments) rests += seg.kind == sequences::SegmentKind::kRest;
  ASSERT_EQ(m.periods.size(), rests);
  EXPECT_LT(m.accel_rmse_ug, 3.0 * accel_floor);
  EXPECT_LT(m.orientation_rmse_mdeg, 3.0 * orient_floor);
  // The reference is the truth here, so there is no body misalignment to find: θ_bp is at the
  // levelling-noise level (a few µrad), far below the arcsec-level ς the compensation removed.
  EXPECT_LT(m.body_misalignment_theta_bp_rad.norm(), 10e-6);
  for (const auto& p : m.periods) {
    EXPECT_GT(p.t_end_s - p.t_begin_s, 20.0);
    EXPECT_TRUE(p.accel_err_n_ug.allFinite());
  }
}

TEST(Evaluation, AccelBiasErrorShowsAsItsVerticalProjection) {
  // Compensating with b_x too large by 30 µg leaves an error -δb in the body frame. A
  // ZUPT-aided INS levels itself: the horizontal part of C_bn δb is indistinguishable from a tilt
  // (the classic tilt/bias ambiguity) and is absorbed within seconds; the vertical part cannot be
  // and remains in the per-period mean. So each rest period shows |δb_x · C_bn(2,0)| and the
  // metric is the RMS of that over the rest positions (plus the noise floor).
  const SimRun& r = shared_run();
  const double db_ug = 30.0;
  ParamSet p = r.unit.params;
  p.accel_bias_mps2.x() += db_ug * kMicroG_mps2;
  const EvaluationMetrics m = evaluate(r.input, p);

  const auto periods = find_rest_periods(r.input, EvaluationOptions{}.min_rest_samples);
  double s = 0.0;
  int x_vertical = 0;
  for (const auto& per : periods) {
    const Eigen::Matrix3d C = true_C_bn_at(r, (per.begin + per.end) / 2);
    s += std::pow(db_ug * C(2, 0), 2);
    if (std::abs(C(2, 0)) > 0.99) ++x_vertical;
  }
  ASSERT_GE(x_vertical, 2) << "the profile must put body x up and down";
  const double predicted = std::sqrt(s / static_cast<double>(periods.size()));
  const double floor = accel_noise_floor_ug(r);
  std::printf(
      "accel RMSE with +30 µg x bias error: %.3f µg; predicted %.3f µg (floor %.3f µg, "
      "true-parameter RMSE %.3f µg)\n",
      m.accel_rmse_ug, predicted, floor, r.truth_metrics.accel_rmse_ug);
  EXPECT_GT(m.accel_rmse_ug, 2.5 * floor);
  EXPECT_GT(m.accel_rmse_ug, 2.0 * r.truth_metrics.accel_rmse_ug);
  EXPECT_NEAR(m.accel_rmse_ug, std::sqrt(predicted * predicted + floor * floor),
              0.15 * predicted + floor);
  // Per period: the vertical error is the projection, with the sign of -δb.
  for (size_t i = 0; i < periods.size(); ++i) {
    const Eigen::Matrix3d C = true_C_bn_at(r, (periods[i].begin + periods[i].end) / 2);
    EXPECT_NEAR(m.periods[i].accel_err_n_ug.z(), -db_ug * C(2, 0), 0.1 * db_ug + 3.0 * floor)
        << "period " << i;
  }
}

TEST(Evaluation, GyroScaleErrorShowsAsHeadingErrorsOfTheRotations) {
  // Compensating with every gyro scale factor 1000 ppm too large under-rotates every turn by
  // 1000 ppm of its angle: the INS attitude error ψ (n frame) grows by ε Δθ_n per rotation. The
  // ZUPT levels away the tilt part; the vertical part is a heading error the INS keeps, so at rest
  // period p the heading is off by H_p = ε Σ_{turns before p} (Δθ_n)_D (90° → 90 mdeg, 180° →
  // 180 mdeg). The fitted γ_np removes the mean; θ_bp can only reduce the rest a little (it is
  // body-fixed, the heading error is not).
  const SimRun& r = shared_run();
  const double eps = 1000e-6;
  ParamSet p = r.unit.params;
  p.gyro_M.diagonal().array() += eps;
  const EvaluationMetrics m = evaluate(r.input, p);

  // Prediction from the reference attitudes: n-frame rotation increments C_k C_{k-1}ᵀ.
  const auto periods = find_rest_periods(r.input, EvaluationOptions{}.min_rest_samples);
  std::vector<double> H;  // heading error per period
  std::vector<double> w;  // number of samples, the RMSE weight
  double heading = 0.0;
  size_t k_prev = 0;
  for (const auto& per : periods) {
    for (size_t k = k_prev + 1; k <= per.begin; ++k)
      heading += eps * matrix_to_rotvec(true_C_bn_at(r, k) * true_C_bn_at(r, k - 1).transpose())(2);
    k_prev = per.begin;
    H.push_back(heading);
    w.push_back(static_cast<double>(per.size()));
  }
  double sw = 0.0, swh = 0.0, peak = 0.0;
  for (size_t i = 0; i < H.size(); ++i) {
    sw += w[i];
    swh += w[i] * H[i];
    peak = std::max(peak, std::abs(H[i]));
  }
  const double mean = swh / sw;
  double sq = 0.0;
  for (size_t i = 0; i < H.size(); ++i) sq += w[i] * (H[i] - mean) * (H[i] - mean);
  const double predicted_mdeg = std::sqrt(sq / sw) * kRadToDeg * 1e3;
  std::printf(
      "orientation RMSE with 1000 ppm gyro scale error: %.2f mdeg; heading-only "
      "prediction (mean removed) %.2f mdeg, peak |H| %.1f mdeg; floor %.4f mdeg\n",
      m.orientation_rmse_mdeg, predicted_mdeg, peak * kRadToDeg * 1e3,
      r.truth_metrics.orientation_rmse_mdeg);
  // Precondition: the profile turns about the vertical (a 90° turn -> 90 mdeg at 1000 ppm).
  ASSERT_GT(peak * kRadToDeg * 1e3, 85.0);
  EXPECT_GT(m.orientation_rmse_mdeg, 10.0 * r.truth_metrics.orientation_rmse_mdeg);
  EXPECT_GT(m.orientation_rmse_mdeg, 10.0 * orientation_noise_floor_mdeg(r));
  EXPECT_LT(m.orientation_rmse_mdeg, 1.15 * predicted_mdeg + 3.0 * orientation_noise_floor_mdeg(r));
  EXPECT_GT(m.orientation_rmse_mdeg, 0.7 * predicted_mdeg);
}

TEST(Evaluation, HeadingOffsetOfTheReferenceIsAbsorbedByGammaNp) {
  // A fixture heading offset δ: the reference says Rz(δ) C_bn_true. The INS finds true north by
  // gyrocompassing (it is only seeded from the reference), so eq. 51 is minimised by
  // C_np(γ_np) Rz(δ) = I, i.e. γ_np = -δ, and the orientation RMSE stays at the floor.
  const SimRun& r = shared_run();
  const double delta = 0.5 * kDegToRad;
  CalibrationInput in = r.input;
  const Eigen::Matrix3d Rz = axis_angle(Eigen::Vector3d::UnitZ(), delta);
  for (auto& ref : in.reference) ref.C_bn_ref = Rz * ref.C_bn_ref;
  const EvaluationMetrics m = evaluate(in, r.unit.params);

  // Gyrocompass accuracy. A heading error γ tilts the INS at Ω_N γ (Ω_N = Ω cos lat); the INS
  // re-levels after every rotation, so each rest p of length T measures that tilt rate anew,
  // limited by ARW (σ² = ARW²/T) and by VRW through the ZUPT velocities (the slope of a white
  // acceleration error over T: σ² = 12 VRW²/(g² T³)). Independent rests combine as 1/σ² = Σ 1/σ_p².
  const double omega_n = 7.292115e-5 * std::cos(factory_site().lat_rad);
  const double arw = r.unit.noise.arw_rad_per_sqrt_s, vrw = r.unit.noise.vrw_mps_per_sqrt_s;
  double info = 0.0;
  for (const auto& per : find_rest_periods(r.input, 100)) {
    const double T = static_cast<double>(per.size()) * r.input.imu[per.begin].dt_s;
    const double rate_var = arw * arw / T + 12.0 * vrw * vrw / (9.8 * 9.8 * T * T * T);
    info += omega_n * omega_n / rate_var;
  }
  const double sigma_gc = 1.0 / std::sqrt(info);
  std::printf(
      "γ_np %.3f mdeg for injected δ %.1f mdeg (gyrocompass σ %.2f mdeg); without "
      "offset γ_np %.3f mdeg; orientation RMSE %.4f mdeg\n",
      m.heading_offset_gamma_np_rad * kRadToDeg * 1e3, delta * kRadToDeg * 1e3,
      sigma_gc * kRadToDeg * 1e3, r.truth_metrics.heading_offset_gamma_np_rad * kRadToDeg * 1e3,
      m.orientation_rmse_mdeg);
  EXPECT_NEAR(m.heading_offset_gamma_np_rad, -delta, 4.0 * sigma_gc);
  EXPECT_NEAR(r.truth_metrics.heading_offset_gamma_np_rad, 0.0, 4.0 * sigma_gc);
  // Same data, same noise: the two fits differ by δ up to second-order terms (δ²/2 ≈ 0.04 mrad).
  EXPECT_NEAR(m.heading_offset_gamma_np_rad - r.truth_metrics.heading_offset_gamma_np_rad, -delta,
              delta * delta);
  EXPECT_LT(m.orientation_rmse_mdeg, 3.0 * orientation_noise_floor_mdeg(r));
}

TEST(Evaluation, AttitudeResidualIsIdentityAtTheTrueMisalignments) {
  // Eq. 51 built by hand: an INS attitude C_ins = C_np(γ) C_ref C_b^bp(θ) leaves no residual.
  const Eigen::Matrix3d C_ref = euler_to_C_bn(0.3, -0.2, 1.1);
  const double gamma = 2e-3;
  const Eigen::Vector3d theta(1e-3, -2e-3, 5e-4);
  const Eigen::Matrix3d C_ins = axis_angle(Eigen::Vector3d::UnitZ(), gamma) * C_ref *
                                euler_to_C_bn(theta(0), theta(1), theta(2));
  EXPECT_LT((attitude_residual(C_ins, C_ref, gamma, theta) - Eigen::Matrix3d::Identity()).norm(),
            1e-14);
  EXPECT_GT((attitude_residual(C_ins, C_ref, 0.0, theta) - Eigen::Matrix3d::Identity()).norm(),
            1e-3);
}

TEST(Evaluation, RejectsMalformedInput) {
  const SimRun& r = shared_run();
  CalibrationInput in = r.input;
  in.reference.pop_back();
  EXPECT_THROW(evaluate(in, r.unit.params), std::invalid_argument);

  in = r.input;
  for (auto& ref : in.reference) ref.at_rest = false;
  try {
    evaluate(in, r.unit.params);
    FAIL() << "no rest period must throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("rest period"), std::string::npos) << e.what();
  }

  in = r.input;
  in.imu[5].dt_s = 0.0;
  try {
    evaluate(in, r.unit.params);
    FAIL() << "zero dt must throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("input.imu[5].dt_s"), std::string::npos) << e.what();
  }

  ParamSet bad = r.unit.params;
  bad.gyro_bias_radps.y() = std::nan("");
  EXPECT_THROW(evaluate(r.input, bad), std::invalid_argument);
}
