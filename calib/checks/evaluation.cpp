#include "calib/checks/evaluation.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <cmath>
#include <stdexcept>
#include <string>

#include "calib/checks/zupt_ins.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

namespace {

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument("evaluate: " + msg); }

std::string idx(const char* field, size_t k) {
  return std::string(field) + "[" + std::to_string(k) + "]";
}

void validate(const CalibrationInput& in, const ParamSet& params, const EvaluationOptions& opt) {
  if (!in.has_reference_attitude())
    fail(std::string("a ") + setting_name(in.setting) +
         " run has no attitude reference; the paper's metrics need a table run (evaluate the "
         "parameters on a factory run of the unit)");
  if (opt.min_rest_samples < 2) fail("options.min_rest_samples must be at least 2");
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0.0))
      fail(std::string("options.") + name + " = " + std::to_string(v) +
           " must be positive and finite");
  };
  positive(opt.decimate_hz, "decimate_hz");
  positive(opt.zupt_sigma_mps, "zupt_sigma_mps");
  positive(opt.depth_sigma_m, "depth_sigma_m");
  positive(opt.filter_hz, "filter_hz");
  positive(opt.initial_tilt_sigma_rad, "initial_tilt_sigma_rad");
  positive(opt.initial_heading_sigma_rad, "initial_heading_sigma_rad");
  if (!(std::isfinite(opt.relevel_tilt_sigma_rad) && opt.relevel_tilt_sigma_rad >= 0.0))
    fail("options.relevel_tilt_sigma_rad must be non-negative and finite");

  if (!params.to_vector().allFinite()) fail("params contain a non-finite value");
  const Eigen::Matrix3d Aa = Eigen::Matrix3d::Identity() + params.accel_M;
  const Eigen::Matrix3d Ag = Eigen::Matrix3d::Identity() + params.gyro_M;
  if (std::abs(Aa.determinant()) < 1e-6) fail("params.accel_M makes I + dM_a singular");
  if (std::abs(Ag.determinant()) < 1e-6) fail("params.gyro_M makes I + dM_g singular");

  if (in.imu.size() < 2) fail("input.imu has " + std::to_string(in.imu.size()) + " samples (< 2)");
  if (in.reference.size() != in.imu.size())
    fail("input.reference has " + std::to_string(in.reference.size()) +
         " samples but input.imu has " + std::to_string(in.imu.size()));
  if (!std::isfinite(in.site.lat_rad) || std::abs(in.site.lat_rad) > 0.5 * kPi ||
      !std::isfinite(in.site.lon_rad) || !std::isfinite(in.site.height_m))
    fail("input.site has a non-finite or out-of-range latitude/longitude/height");
  if (in.site.gravity_mps2 && !(std::isfinite(*in.site.gravity_mps2) && *in.site.gravity_mps2 > 0))
    fail("input.site.gravity_mps2 must be positive and finite");
  for (size_t k = 0; k < in.imu.size(); ++k) {
    const ImuIncrement& s = in.imu[k];
    if (!(std::isfinite(s.dt_s) && s.dt_s > 0.0))
      fail(idx("input.imu", k) + ".dt_s = " + std::to_string(s.dt_s) +
           " must be positive and finite");
    if (!std::isfinite(s.t_s) || !s.dtheta_rad.allFinite() || !s.dv_mps.allFinite())
      fail(idx("input.imu", k) + " has a non-finite time or increment");
    if (k > 0 && !(s.t_s > in.imu[k - 1].t_s))
      fail(idx("input.imu", k) + ".t_s = " + std::to_string(s.t_s) + " does not increase");
    const ReferenceSample& r = in.reference[k];
    if (!std::isfinite(r.t_s) || std::abs(r.t_s - s.t_s) > 0.5 * s.dt_s)
      fail(idx("input.reference", k) + ".t_s = " + std::to_string(r.t_s) +
           " is not on the IMU time axis (imu t_s = " + std::to_string(s.t_s) + ")");
    if (!r.C_bn_ref.allFinite() ||
        (r.C_bn_ref.transpose() * r.C_bn_ref - Eigen::Matrix3d::Identity()).norm() > 1e-6)
      fail(idx("input.reference", k) + ".C_bn_ref is not a rotation matrix");
  }
}

/// The constant factors of eq. 51 for one parameter vector p = (γ_np, θ_bp): residual
/// C_ins (L C_ref R)ᵀ = C_ins Rᵀ C_refᵀ Lᵀ with L = C_np(γ_np), R = C_b^bp(θ_bp).
struct FitFactors {
  Eigen::Matrix3d Rt, Lt;
  explicit FitFactors(const Eigen::Vector4d& p)
      : Rt(euler_to_C_bn(p(1), p(2), p(3)).transpose()),
        Lt(axis_angle(Eigen::Vector3d::UnitZ(), p(0)).transpose()) {}
  /// j(r) of eq. 52: the residual's Euler angles (roll, pitch, yaw).
  Eigen::Vector3d residual(const Eigen::Matrix3d& C_ins, const Eigen::Matrix3d& C_ref) const {
    const Eigen::Matrix3d a = C_ins.lazyProduct(Rt);
    const Eigen::Matrix3d b = a.lazyProduct(C_ref.transpose());
    return C_bn_to_euler(b.lazyProduct(Lt));
  }
};

struct MisalignmentFit {
  double gamma_np_rad = 0.0;
  Eigen::Vector3d theta_bp_rad = Eigen::Vector3d::Zero();
};

double fit_cost(const std::vector<Eigen::Matrix3d>& C_ins,
                const std::vector<Eigen::Matrix3d>& C_ref, const Eigen::Vector4d& p) {
  const FitFactors f(p);
  double c = 0.0;
  for (size_t i = 0; i < C_ins.size(); ++i) c += f.residual(C_ins[i], C_ref[i]).squaredNorm();
  return c;
}

/// Eq. 52 by Gauss-Newton with forward-difference Jacobians (4 parameters; the residuals are
/// milliradians, so one or two iterations converge). A rank-deficient sequence (e.g. rotations
/// about the vertical only, where γ_np and the body yaw are the same rotation) gets the
/// minimum-norm step instead of a blow-up.
MisalignmentFit fit_misalignments(const std::vector<Eigen::Matrix3d>& C_ins,
                                  const std::vector<Eigen::Matrix3d>& C_ref) {
  Eigen::Vector4d p = Eigen::Vector4d::Zero();
  double cost = fit_cost(C_ins, C_ref, p);
  constexpr double h = 1e-7;
  for (int iter = 0; iter < 20; ++iter) {
    const FitFactors f0(p);
    std::vector<FitFactors> fj;
    for (int j = 0; j < 4; ++j) fj.emplace_back(p + h * Eigen::Vector4d::Unit(j));
    Eigen::Matrix4d JtJ = Eigen::Matrix4d::Zero();
    Eigen::Vector4d Jte = Eigen::Vector4d::Zero();
    for (size_t i = 0; i < C_ins.size(); ++i) {
      const Eigen::Vector3d e0 = f0.residual(C_ins[i], C_ref[i]);
      Eigen::Matrix<double, 3, 4> J;
      for (int j = 0; j < 4; ++j) J.col(j) = (fj[j].residual(C_ins[i], C_ref[i]) - e0) / h;
      JtJ.noalias() += J.transpose() * J;
      Jte.noalias() += J.transpose() * e0;
    }
    const Eigen::Vector4d dp = -JtJ.completeOrthogonalDecomposition().solve(Jte);
    // Converged: a step this small changes the cost only at round-off, where the line search
    // below would halve it a dozen times for nothing (each halving a pass over every record).
    if (dp.norm() < 1e-11) break;
    // Step halving keeps the cost monotone if the linearisation is poor.
    double step = 1.0;
    bool improved = false;
    for (int halving = 0; halving < 12; ++halving, step *= 0.5) {
      const Eigen::Vector4d trial = p + step * dp;
      const double c = fit_cost(C_ins, C_ref, trial);
      if (c <= cost) {
        p = trial;
        cost = c;
        improved = true;
        break;
      }
    }
    if (!improved || (step * dp).norm() < 1e-11) break;
  }
  return {p(0), p.tail<3>()};
}

}  // namespace

Eigen::Matrix3d attitude_residual(const Eigen::Matrix3d& C_bn_ins,
                                  const Eigen::Matrix3d& C_bn_ref_true, double gamma_np_rad,
                                  const Eigen::Vector3d& theta_bp_rad) {
  const Eigen::Matrix3d C_np_n = axis_angle(Eigen::Vector3d::UnitZ(), gamma_np_rad);
  const Eigen::Matrix3d C_b_bp = euler_to_C_bn(theta_bp_rad(0), theta_bp_rad(1), theta_bp_rad(2));
  return C_bn_ins * (C_np_n * C_bn_ref_true * C_b_bp).transpose();
}

namespace {

/// The run as the evaluation sees it: compensated with the shared error model (inverse of eq. 18
/// and 23) where used — storing the compensated run would cost 17 MB per evaluation, recomputing
/// it nine multiply-adds a sample — and the reference corrected for the table misalignment ς
/// (eq. 30-31): C_bn_true = exp([ς x]) C_bn_table.
struct EvalRun {
  const CalibrationInput& in;
  const EvaluationOptions& opt;
  ImuCompensator model;
  Eigen::Matrix3d C_sigma;
  EarthModel earth;
  ZuptInsOptions zopt;
  size_t n;
  double mean_dt_s;

  EvalRun(const CalibrationInput& input, const ParamSet& params, const EvaluationOptions& o)
      : in(input),
        opt(o),
        model(params),
        C_sigma(rotvec_to_matrix<double>(params.table_misalignment_rad)),
        earth(input.site),
        n(input.imu.size()),
        mean_dt_s((input.imu.back().t_s - input.imu.front().t_s) /
                  static_cast<double>(input.imu.size() - 1)) {
    zopt.filter_hz = o.filter_hz;
    zopt.zupt_sigma_mps = o.zupt_sigma_mps;
    zopt.depth_sigma_m = o.depth_sigma_m;
    zopt.tilt_sigma_after_motion_rad = o.relevel_tilt_sigma_rad;
    zopt.heading_sigma_after_motion_rad = o.reopen_heading_sigma_rad;
  }
  Eigen::Vector3d dtheta(size_t k) const {
    return model.dtheta(in.imu[k].dtheta_rad, in.imu[k].dt_s);
  }
  Eigen::Vector3d dv(size_t k) const { return model.dv(in.imu[k].dv_mps, in.imu[k].dt_s); }
  Eigen::Matrix3d C_ref_true(size_t k) const { return C_sigma * in.reference[k].C_bn_ref; }
};

struct InitialAttitude {
  Eigen::Vector3d psi0 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d P = Eigen::Matrix3d::Zero();
};

/// Pass 1: the INS finds its own heading by gyrocompassing (ZUPT only) from a loose prior on the
/// reference's; the clone states return the smoothed initial attitude error (the paper uses RTS
/// smoothing for the same purpose, §VII). Only its end result is used, so it runs on increments
/// combined to the filter rate (exactly, per conventions.hpp: dθ = log Π exp([dθ_k x]), dv in the
/// body frame at the block start), which saves most of the strapdown cost of a 100 Hz stream.
InitialAttitude gyrocompass(const EvalRun& run, const NavState& nav0) {
  const EvaluationOptions& opt = run.opt;
  Eigen::Matrix3d P_psi0 = Eigen::Matrix3d::Zero();
  P_psi0.diagonal() << opt.initial_tilt_sigma_rad * opt.initial_tilt_sigma_rad,
      opt.initial_tilt_sigma_rad * opt.initial_tilt_sigma_rad,
      opt.initial_heading_sigma_rad * opt.initial_heading_sigma_rad;
  const size_t block =
      std::max<size_t>(1, static_cast<size_t>(std::lround(1.0 / (opt.filter_hz * run.mean_dt_s))));
  ZuptIns ins(run.earth, run.in.noise, run.zopt);
  ins.initialize(nav0, P_psi0);
  for (size_t k0 = 1; k0 < run.n; k0 += block) {
    const size_t k1 = std::min(run.n, k0 + block);
    Eigen::Matrix3d C_b_b0 = Eigen::Matrix3d::Identity();
    Eigen::Vector3d dv_b0 = Eigen::Vector3d::Zero();
    double dt_s = 0.0;
    bool all_at_rest = true;
    for (size_t k = k0; k < k1; ++k) {
      dv_b0 += C_b_b0 * run.dv(k);
      C_b_b0 = C_b_b0 * rotvec_to_matrix<double>(run.dtheta(k));
      dt_s += run.in.imu[k].dt_s;
      all_at_rest = all_at_rest && run.in.reference[k].at_rest;
    }
    ins.step(matrix_to_rotvec(C_b_b0), dv_b0, dt_s, all_at_rest);
  }
  return {ins.initial_attitude_error(), ins.initial_attitude_covariance()};
}

/// What pass 2 records: per rest period the summed specific-force error (eq. 53-54), and the INS
/// and reference attitudes at the decimated rest samples (eq. 51-52).
struct Recorded {
  std::vector<Eigen::Vector3d> accel_sum;
  std::vector<size_t> accel_count;
  std::vector<Eigen::Matrix3d> att_ins, att_ref;
  std::vector<size_t> att_period;
};

/// Pass 2 from the smoothed initial attitude. Heading is now held by the gyros: its prior is what
/// ARW adds in one filter interval, so the aiding levels the INS but cannot gyrocompass away the
/// heading errors a poor gyro calibration causes — those are what eq. 51 measures.
Recorded evaluation_pass(const EvalRun& run, const std::vector<RestPeriod>& periods,
                         const NavState& nav0, const InitialAttitude& init) {
  const EvaluationOptions& opt = run.opt;
  NavState nav1 = nav0;
  nav1.C_bn = orthonormalize(rotvec_to_matrix<double>(init.psi0) * nav0.C_bn);
  Eigen::Matrix3d P_psi1 = Eigen::Matrix3d::Zero();
  P_psi1.block<2, 2>(0, 0) = init.P.block<2, 2>(0, 0);
  const double heading_hold_sigma =
      std::max(run.in.noise.arw_rad_per_sqrt_s / std::sqrt(opt.filter_hz), 1e-9);
  P_psi1(2, 2) = heading_hold_sigma * heading_hold_sigma;
  const size_t decim = std::max<size_t>(
      1, static_cast<size_t>(std::lround(1.0 / (opt.decimate_hz * run.mean_dt_s))));
  const Eigen::Vector3d g_n = run.earth.g_n();
  const Eigen::Vector3d w_ie_n = run.earth.w_ie_n();

  Recorded rec;
  rec.accel_sum.assign(periods.size(), Eigen::Vector3d::Zero());
  rec.accel_count.assign(periods.size(), 0);
  size_t expected_att = 0;
  for (const auto& p : periods) expected_att += (p.size() + decim - 1) / decim;
  rec.att_ins.reserve(expected_att);
  rec.att_ref.reserve(expected_att);
  rec.att_period.reserve(expected_att);

  ZuptIns ins(run.earth, run.in.noise, run.zopt);
  ins.initialize(nav1, P_psi1);
  size_t pi = 0;  // first period that has not ended before sample k
  auto record = [&](size_t k) {
    while (pi < periods.size() && periods[pi].end <= k) ++pi;
    if (pi < periods.size() && k >= periods[pi].begin && (k - periods[pi].begin) % decim == 0) {
      rec.att_ins.push_back(ins.nav().C_bn);
      rec.att_ref.push_back(run.C_ref_true(k));
      rec.att_period.push_back(pi);
    }
  };
  record(0);
  for (size_t k = 1; k < run.n; ++k) {
    const Eigen::Vector3d dv_k = run.dv(k);
    while (pi < periods.size() && periods[pi].end <= k) ++pi;
    if (pi < periods.size() && k >= periods[pi].begin) {
      // Eq. 53-54. dv_k is expressed in the body frame at t_{k-1} (conventions.hpp), so it is
      // resolved with the attitude before the step and turned by half the n-frame rotation over
      // the interval; at rest the expected specific force is -g_n (NED, g down), so the error is
      // f_n + g_n (the paper's "- [0 0 g]" with g counted upward).
      const double dt = run.in.imu[k].dt_s;
      const Eigen::Vector3d f_n =
          (Eigen::Matrix3d::Identity() - 0.5 * skew<double>(Eigen::Vector3d(w_ie_n * dt))) *
          ins.nav().C_bn * dv_k / dt;
      rec.accel_sum[pi] += f_n + g_n;
      ++rec.accel_count[pi];
    }
    ins.step(run.dtheta(k), dv_k, run.in.imu[k].dt_s, run.in.reference[k].at_rest);
    record(k);
  }
  return rec;
}

/// Eq. 51-54 from what pass 2 recorded: the fitted heading offset and body misalignment, the
/// orientation RMSE after them, and the acceleration RMSE over the rest periods.
EvaluationMetrics metrics_from(const EvalRun& run, const std::vector<RestPeriod>& periods,
                               const Recorded& rec) {
  EvaluationMetrics m;
  const MisalignmentFit fit = fit_misalignments(rec.att_ins, rec.att_ref);
  const FitFactors fitted((Eigen::Vector4d() << fit.gamma_np_rad, fit.theta_bp_rad).finished());
  m.heading_offset_gamma_np_rad = fit.gamma_np_rad;
  m.body_misalignment_theta_bp_rad = fit.theta_bp_rad;

  constexpr double kRadToMdeg = kRadToDeg * 1e3;
  std::vector<double> period_sq(periods.size(), 0.0);
  std::vector<size_t> period_n(periods.size(), 0);
  double total_sq = 0.0;
  for (size_t i = 0; i < rec.att_ins.size(); ++i) {
    const double e2 = fitted.residual(rec.att_ins[i], rec.att_ref[i]).squaredNorm();
    total_sq += e2;
    period_sq[rec.att_period[i]] += e2;
    ++period_n[rec.att_period[i]];
  }
  m.orientation_rmse_mdeg =
      std::sqrt(total_sq / static_cast<double>(std::max<size_t>(rec.att_ins.size(), 1))) *
      kRadToMdeg;

  double accel_sq = 0.0;
  m.periods.reserve(periods.size());
  for (size_t p = 0; p < periods.size(); ++p) {
    RestPeriodMetric pm;
    pm.t_begin_s = run.in.imu[periods[p].begin].t_s;
    pm.t_end_s = run.in.imu[periods[p].end - 1].t_s;
    pm.accel_err_n_ug = rec.accel_sum[p] /
                        static_cast<double>(std::max<size_t>(rec.accel_count[p], 1)) / kMicroG_mps2;
    pm.orientation_rms_mdeg =
        std::sqrt(period_sq[p] / static_cast<double>(std::max<size_t>(period_n[p], 1))) *
        kRadToMdeg;
    accel_sq += pm.accel_err_n_ug.squaredNorm();
    m.periods.push_back(pm);
  }
  m.accel_rmse_ug = std::sqrt(accel_sq / static_cast<double>(periods.size()));
  return m;
}

}  // namespace

EvaluationMetrics evaluate(const CalibrationInput& in, const ParamSet& params,
                           const EvaluationOptions& opt) {
  validate(in, params, opt);
  const std::vector<RestPeriod> periods = find_rest_periods(in, opt.min_rest_samples);
  if (periods.empty())
    fail("no rest period of at least " + std::to_string(opt.min_rest_samples) +
         " samples (options.min_rest_samples) in input.reference");
  const EvalRun run(in, params, opt);
  NavState nav0;
  nav0.lat_rad = in.site.lat_rad;
  nav0.lon_rad = in.site.lon_rad;
  nav0.height_m = in.site.height_m;
  nav0.C_bn = run.C_ref_true(0);
  const InitialAttitude init = gyrocompass(run, nav0);
  return metrics_from(run, periods, evaluation_pass(run, periods, nav0, init));
}

}  // namespace imucal::calib::checks
