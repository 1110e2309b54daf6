#pragma once
// The evaluation's own ZUPT-aided INS (paper §VII): a 9-state error-state Kalman filter
// (ψ, δv, δp) with closed-loop reset, aided only while at rest by zero velocity (eq. 36-39) and
// mean depth (eq. 40-43). It shares the strapdown mechanisation (calib/core/strapdown.hpp) but
// nothing with AINS or NLSQ, so it can judge both.
//
// Three extra states clone the initial attitude error ψ0 (a fixed-point smoother by state
// augmentation): they never propagate and are never reset, so at the end of a run their estimate
// is ψ0 given all the data — the "improved initial heading" the paper gets from RTS smoothing,
// without storing the run.
//
// Error conventions (conventions.hpp): Ĉ_bn = (I - [ψ x]) C_bn, δv = v̂ - v, δp = p̂ - p with p in
// local NED metres (δN, δE, δD).
#include <Eigen/Core>

#include "calib/core/earth.hpp"
#include "calib/core/noise_model.hpp"
#include "calib/core/strapdown.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

struct ZuptInsOptions {
  double filter_hz = 10.0;       ///< covariance propagation + aiding rate
  double zupt_sigma_mps = 1e-4;  ///< zero-velocity observation noise, per axis
  double depth_sigma_m = 1e-2;   ///< mean-depth observation noise
  double initial_velocity_sigma_mps = 1e-3;
  double initial_position_sigma_m = 1e-2;
  /// Tilt uncertainty added when the unit comes to rest after motion (0 = off): lets the ZUPT
  /// re-level quickly after a rotation with an imperfect calibration.
  double tilt_sigma_after_motion_rad = 1e-3;
  /// Heading uncertainty added at the same moment (0 = off: heading stays as the gyros left it).
  /// Non-zero, the ZUPT-aided INS re-finds its heading at every rest by gyrocompassing, as an INS
  /// whose heading is aided only through Earth rate does.
  double heading_sigma_after_motion_rad = 0.0;
};

class ZuptIns {
 public:
  static constexpr int kPsi = 0, kVel = 3, kPos = 6, kPsi0 = 9, kStates = 12;
  using StateVector = Eigen::Matrix<double, kStates, 1>;
  using StateCovariance = Eigen::Matrix<double, kStates, kStates>;

  /// Throws std::invalid_argument if an option or noise figure is not positive and finite.
  ZuptIns(const EarthModel& earth, const NoiseModel& noise, const ZuptInsOptions& options);

  /// Start at nav0 (at rest, depth = -nav0.height_m is the mean depth to hold) with the given
  /// n-frame covariance of the attitude error ψ (also the clone's, fully correlated with it).
  void initialize(const NavState& nav0, const Eigen::Matrix3d& P_psi0_rad2);

  /// One compensated increment ending at a sample whose reference says at_rest or not. The
  /// filter predicts and (if at rest) aids at filter_hz; the strapdown runs every sample.
  void step(const Eigen::Vector3d& dtheta_rad, const Eigen::Vector3d& dv_mps, double dt_s,
            bool at_rest);

  const NavState& nav() const { return nav_; }
  const Strapdown& strapdown() const { return strapdown_; }
  /// Smoothed estimate of the initial attitude error ψ(t0) given the data so far: the corrected
  /// initial attitude is exp([ψ0 x]) Ĉ_bn(t0).
  Eigen::Vector3d initial_attitude_error() const { return x_.segment<3>(kPsi0); }
  Eigen::Matrix3d initial_attitude_covariance() const { return P_.block<3, 3>(kPsi0, kPsi0); }
  /// Current attitude error covariance (n frame).
  Eigen::Matrix3d attitude_covariance() const { return P_.block<3, 3>(kPsi, kPsi); }
  int aiding_updates() const { return aiding_updates_; }

 private:
  void update_transition(double dt_s);
  void predict(double dt_s);
  void update_scalar(int state_index, double innovation, double sigma);
  void reset_nav();

  Strapdown strapdown_;
  ZuptInsOptions opt_;
  double q_psi_rad2ps_ = 0.0;  ///< PSD of the attitude random walk
  double q_vel_m2ps3_ = 0.0;   ///< PSD of the velocity random walk
  NavState nav_;
  double depth0_m_ = 0.0;
  StateVector x_ = StateVector::Zero();
  StateCovariance P_ = StateCovariance::Zero();
  double acc_dt_s_ = 0.0;          ///< time since the last filter epoch
  double transition_dt_s_ = -1.0;  ///< interval Φ9_ and Qd9_ were computed for
  Eigen::Matrix<double, 9, 9> Phi9_ = Eigen::Matrix<double, 9, 9>::Identity();
  Eigen::Matrix<double, 9, 9> Qd9_ = Eigen::Matrix<double, 9, 9>::Zero();
  int aiding_updates_ = 0;
  bool moved_since_aiding_ = false;
  bool initialized_ = false;
};

}  // namespace imucal::calib::checks
