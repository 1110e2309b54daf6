#include "calib/checks/zupt_ins.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "calib/core/rotation.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

namespace {

void require_positive(double v, const char* what) {
  if (!(std::isfinite(v) && v > 0.0))
    throw std::invalid_argument(std::string("ZuptIns: ") + what + " = " + std::to_string(v) +
                                " must be positive and finite");
}

void require_non_negative(double v, const char* what) {
  if (!(std::isfinite(v) && v >= 0.0))
    throw std::invalid_argument(std::string("ZuptIns: noise ") + what + " = " + std::to_string(v) +
                                " must be non-negative and finite");
}

}  // namespace

ZuptIns::ZuptIns(const EarthModel& earth, const NoiseModel& noise, const ZuptInsOptions& options)
    : strapdown_(earth), opt_(options) {
  require_positive(opt_.filter_hz, "filter_hz");
  require_positive(opt_.zupt_sigma_mps, "zupt_sigma_mps");
  require_positive(opt_.depth_sigma_m, "depth_sigma_m");
  require_positive(opt_.initial_velocity_sigma_mps, "initial_velocity_sigma_mps");
  require_positive(opt_.initial_position_sigma_m, "initial_position_sigma_m");
  if (!(std::isfinite(opt_.tilt_sigma_after_motion_rad) && opt_.tilt_sigma_after_motion_rad >= 0.0))
    throw std::invalid_argument(
        "ZuptIns: tilt_sigma_after_motion_rad must be non-negative and finite");
  if (!(std::isfinite(opt_.heading_sigma_after_motion_rad) &&
        opt_.heading_sigma_after_motion_rad >= 0.0))
    throw std::invalid_argument(
        "ZuptIns: heading_sigma_after_motion_rad must be non-negative and finite");
  require_non_negative(noise.arw_rad_per_sqrt_s, "arw_rad_per_sqrt_s");
  require_non_negative(noise.vrw_mps_per_sqrt_s, "vrw_mps_per_sqrt_s");
  require_non_negative(noise.gyro_bias_instability_radps, "gyro_bias_instability_radps");
  require_non_negative(noise.accel_bias_instability_mps2, "accel_bias_instability_mps2");
  require_non_negative(noise.gyro_bias_tau_s, "gyro_bias_tau_s");
  require_non_negative(noise.accel_bias_tau_s, "accel_bias_tau_s");
  // The 9-state filter has no bias states, so a Gauss-Markov bias (σ, τ) enters as extra white
  // noise of PSD 2σ²τ: its integral's variance for t << τ is σ²t², below 2σ²τt while t < 2τ, and
  // equals 2σ²τt for t >> τ — a bound over the whole run.
  const double arw = noise.arw_rad_per_sqrt_s, vrw = noise.vrw_mps_per_sqrt_s;
  q_psi_rad2ps_ = arw * arw + 2.0 * noise.gyro_bias_instability_radps *
                                  noise.gyro_bias_instability_radps * noise.gyro_bias_tau_s;
  q_vel_m2ps3_ = vrw * vrw + 2.0 * noise.accel_bias_instability_mps2 *
                                 noise.accel_bias_instability_mps2 * noise.accel_bias_tau_s;
  // A perfectly noiseless model would make the filter trust the INS absolutely; keep a floor
  // far below any real sensor so the covariance stays positive definite.
  q_psi_rad2ps_ = std::max(q_psi_rad2ps_, 1e-20);
  q_vel_m2ps3_ = std::max(q_vel_m2ps3_, 1e-18);
}

void ZuptIns::initialize(const NavState& nav0, const Eigen::Matrix3d& P_psi0_rad2) {
  if (!P_psi0_rad2.allFinite() || P_psi0_rad2.diagonal().minCoeff() <= 0.0)
    throw std::invalid_argument(
        "ZuptIns::initialize: initial attitude covariance must be "
        "finite with a positive diagonal");
  nav_ = nav0;
  depth0_m_ = -nav0.height_m;
  x_.setZero();
  P_.setZero();
  P_.block<3, 3>(kPsi, kPsi) = P_psi0_rad2;
  P_.block<3, 3>(kPsi0, kPsi0) = P_psi0_rad2;
  P_.block<3, 3>(kPsi, kPsi0) = P_psi0_rad2;  // the clone *is* ψ at t0
  P_.block<3, 3>(kPsi0, kPsi) = P_psi0_rad2;
  P_.block<3, 3>(kVel, kVel) = Eigen::Matrix3d::Identity() * opt_.initial_velocity_sigma_mps *
                               opt_.initial_velocity_sigma_mps;
  P_.block<3, 3>(kPos, kPos) =
      Eigen::Matrix3d::Identity() * opt_.initial_position_sigma_m * opt_.initial_position_sigma_m;
  acc_dt_s_ = 0.0;
  aiding_updates_ = 0;
  moved_since_aiding_ = false;
  initialized_ = true;
}

void ZuptIns::step(const Eigen::Vector3d& dtheta_rad, const Eigen::Vector3d& dv_mps, double dt_s,
                   bool at_rest) {
  if (!initialized_) throw std::logic_error("ZuptIns::step called before initialize");
  if (!at_rest) moved_since_aiding_ = true;
  acc_dt_s_ += dt_s;
  strapdown_.step(nav_, dtheta_rad, dv_mps, dt_s);

  // Filter epoch once an interval of 1/filter_hz is complete (half a sample of slack so a
  // 100 Hz stream gives exactly every 10th sample at 10 Hz despite round-off in dt).
  if (acc_dt_s_ < 1.0 / opt_.filter_hz - 0.5 * dt_s) return;
  predict(acc_dt_s_);
  acc_dt_s_ = 0.0;
  if (!at_rest) return;

  if (moved_since_aiding_) {
    // Motion may have tilted the INS by more than its noise model allows (a calibration under
    // test is not the truth): reopen the tilt so the ZUPT re-levels within a second or two
    // instead of over a tuning-dependent fraction of the rest. Heading stays as the gyros left it
    // unless heading_sigma_after_motion_rad reopens it too.
    P_(kPsi, kPsi) += opt_.tilt_sigma_after_motion_rad * opt_.tilt_sigma_after_motion_rad;
    P_(kPsi + 1, kPsi + 1) += opt_.tilt_sigma_after_motion_rad * opt_.tilt_sigma_after_motion_rad;
    P_(kPsi + 2, kPsi + 2) +=
        opt_.heading_sigma_after_motion_rad * opt_.heading_sigma_after_motion_rad;
    moved_since_aiding_ = false;
  }

  // Zero velocity, eq. 36-39: the observed difference is δv itself (H = I).
  for (int i = 0; i < 3; ++i) update_scalar(kVel + i, nav_.v_n_mps(i), opt_.zupt_sigma_mps);
  // Mean depth, eq. 40-43: δd = d̂ - d0 (H = 1 on δD).
  update_scalar(kPos + 2, -nav_.height_m - depth0_m_, opt_.depth_sigma_m);
  P_ = 0.5 * (P_ + P_.transpose()).eval();  // keep round-off from breaking symmetry
  ++aiding_updates_;
  reset_nav();
}

void ZuptIns::update_transition(double dt_s) {
  // The error dynamics are evaluated at the nominal station state: at rest (or turning on the
  // table) the specific force in n is the reaction to gravity, f_n = -g_n, the velocity is zero
  // and the position is the site. F is then constant, so Φ and Q_d are computed once per
  // interval length rather than every epoch.
  const Site& site = strapdown_.earth().site();
  const Eigen::Vector3d w_ie_n = EarthModel::w_ie_n_at(site.lat_rad);
  const double g = strapdown_.earth().gravity_mps2();
  const Eigen::Vector3d f_n(0.0, 0.0, -g);
  const double R = std::sqrt(EarthModel::radius_north_m(site.lat_rad) *
                             EarthModel::radius_east_m(site.lat_rad)) +
                   site.height_m;

  // Continuous error dynamics, one line per equation of the paper.
  using M9 = Eigen::Matrix<double, 9, 9>;
  M9 F = M9::Zero();
  F.block<3, 3>(kPsi, kPsi) = -skew<double>(w_ie_n);        // eq. 6: -ω_in x ψ (v = 0)
  F.block<3, 3>(kVel, kPsi) = skew<double>(f_n);            // eq. 7/21: [f_n x] ψ
  F.block<3, 3>(kVel, kVel) = -skew<double>(2.0 * w_ie_n);  // eq. 7: Coriolis
  F(kVel + 2, kPos + 2) = 2.0 * g / R;  // δg: gravity grows with depth — the unstable vertical
  F.block<3, 3>(kPos, kVel) = Eigen::Matrix3d::Identity();  // eq. 8

  // Φ = exp(F dt) to third order: the large entries form the nilpotent chain δp←δv←ψ, the rest
  // are Earth-rate sized, so the series is exact to far below the noise for dt ≲ 1 s.
  const M9 A = F * dt_s;
  const M9 A2 = A * A;
  Phi9_ = M9::Identity() + A + 0.5 * A2 + (1.0 / 6.0) * A2 * A;

  // Sensor noise enters ψ and δv rotated by C_bn; both spectra are isotropic, so C Q Cᵀ = Q.
  M9 Qc = M9::Zero();
  Qc.block<3, 3>(kPsi, kPsi).diagonal().setConstant(q_psi_rad2ps_);
  Qc.block<3, 3>(kVel, kVel).diagonal().setConstant(q_vel_m2ps3_);
  Qd9_ = 0.5 * (Phi9_ * Qc * Phi9_.transpose() + Qc) * dt_s;  // trapezoid
  transition_dt_s_ = dt_s;
}

void ZuptIns::predict(double dt_s) {
  if (std::abs(dt_s - transition_dt_s_) > 1e-9 * dt_s) update_transition(dt_s);
  // The clone block does not propagate: Φ = diag(Φ9, I3). (lazyProduct: fixed 9x9 products are
  // faster coefficient-wise than through Eigen's blocked GEMM.)
  using M9 = Eigen::Matrix<double, 9, 9>;
  const M9 PhiP = Phi9_.lazyProduct(P_.block<9, 9>(0, 0));
  P_.block<9, 9>(0, 0) = PhiP.lazyProduct(Phi9_.transpose()) + Qd9_;
  const Eigen::Matrix<double, 9, 3> PhiPnc = Phi9_.lazyProduct(P_.block<9, 3>(0, kPsi0));
  P_.block<9, 3>(0, kPsi0) = PhiPnc;
  P_.block<3, 9>(kPsi0, 0) = PhiPnc.transpose();
  // Nav states are zero after every reset, so only the (never reset) clone has a mean: Φ x = x.
}

void ZuptIns::update_scalar(int j, double z, double sigma) {
  const double S = P_(j, j) + sigma * sigma;
  const StateVector K = P_.col(j) / S;
  x_ += K * (z - x_(j));
  P_ -= (K * S).lazyProduct(K.transpose());
}

void ZuptIns::reset_nav() {
  // Closed-loop reset: Ĉ = (I - [ψ x]) C  =>  C = exp([ψ x]) Ĉ;  v = v̂ - δv;  p = p̂ - δp.
  const Eigen::Vector3d psi = x_.segment<3>(kPsi);
  nav_.C_bn = orthonormalize(rotvec_to_matrix<double>(psi) * nav_.C_bn);
  nav_.v_n_mps -= x_.segment<3>(kVel);
  const Eigen::Vector3d dp = x_.segment<3>(kPos);
  nav_.lat_rad -= dp(0) / (EarthModel::radius_north_m(nav_.lat_rad) + nav_.height_m);
  nav_.lon_rad -=
      dp(1) / ((EarthModel::radius_east_m(nav_.lat_rad) + nav_.height_m) * std::cos(nav_.lat_rad));
  nav_.height_m += dp(2);  // d = -h
  x_.head<9>().setZero();
}

}  // namespace imucal::calib::checks
