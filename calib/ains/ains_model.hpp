#pragma once
// AINS error-state model (paper §IV, ARCHITECTURE §6): the 36-state layout, the mapping between the
// filter's sensor states and the ParamSet's flat order, and the linearised dynamics (eq. 6-8,
// 21-22, 26-27) in KF-GINS style — one F.block(...) line per term of the paper's equations.
//
// Error definitions (all "nominal minus truth" for the navigation states, conventions.hpp):
//   ψ   attitude error, Ĉ_bn = (I - [ψ x]) C_bn                                   (paper eq. 6)
//   δv  v̂_n - v_n [m/s], NED                                                     (paper eq. 7)
//   δp  p̂ - p as NED metres [m] (north, east, down)                              (paper eq. 8)
// and for the sensor states the *remaining* parameter error "truth minus nominal":
//   Δb_a, ΔM_a, Δb_g, ΔM_g, Δς such that θ_true = θ_nominal + Δθ.
// With the nominal compensation f̂ = (I + M̂_a)^-1 (f~ - b̂_a) the compensated-measurement error is
//   δf = f̂ - f = (I + M̂_a)^-1 (Δb_a + ΔM_a f)        (eq. 18 inverted; eq. 23 likewise for ω)
// so the paper's eq. 22 and 27 carry an extra factor (I + M̂)^-1 (≈ I, exact at the nominal).
#include <Eigen/Core>

#include "calib/core/earth.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::calib::ains {
using namespace calib::core;

/// Block offsets of the 36-element error state (paper: 9 nav + 24 sensor + 3 table misalignment).
/// dM blocks are stored column-major (dM(0,c), dM(1,c), dM(2,c) for c = 0..2) so that the block for
/// column c is the "I3 f_c" block of eq. 22 / "I3 ω_c" block of eq. 27: δM f = Σ_c col_c(δM) f_c.
enum StateID : int {
  kPsi = 0,        ///< ψ, rad
  kVel = 3,        ///< δv_n, m/s
  kPos = 6,        ///< δp NED, m
  kAccBias = 9,    ///< Δb_a, m/s^2
  kAccM = 12,      ///< ΔM_a, column-major, dimensionless
  kGyroBias = 21,  ///< Δb_g, rad/s
  kGyroM = 24,     ///< ΔM_g, column-major
  kTableMis = 33,  ///< Δς, rad (paper eq. 30-31)
  kNumStates = 36,
  kNumNav = 9,
  kNumSensor = 27,  ///< states 9..35 (sensor + table misalignment)
};

using StateVec = Eigen::Matrix<double, kNumStates, 1>;
using StateCov = Eigen::Matrix<double, kNumStates, kNumStates>;
using NavMat = Eigen::Matrix<double, kNumNav, kNumNav>;
/// Coupling of the sensor block into the navigation block (F_ns, Φ_ns): 9 x 27.
using NavSensorMat = Eigen::Matrix<double, kNumNav, kNumSensor>;

/// State index of ParamSet flat index p (0..26). ParamSet stores dM row-major, the state
/// column-major: ParamSet M(r,c) at 3 + 3r + c  <->  state kAccM + 3c + r.
inline int state_index_of_param(int p) {
  auto matrix_entry = [](int offset, int rc) { return offset + 3 * (rc % 3) + rc / 3; };
  if (p < 3) return kAccBias + p;
  if (p < 12) return matrix_entry(kAccM, p - 3);
  if (p < 15) return kGyroBias + (p - 12);
  if (p < 24) return matrix_entry(kGyroM, p - 15);
  return kTableMis + (p - 24);
}

/// The sensor part of a state vector (or any 36-vector) in ParamSet flat order.
inline ParamVector sensor_states_to_params(const StateVec& x) {
  ParamVector p;
  for (int i = 0; i < ParamSet::kSize; ++i) p(i) = x(state_index_of_param(i));
  return p;
}

/// The parameter block of a state covariance, in ParamSet flat order.
inline ParamCovariance sensor_cov_to_params(const StateCov& P) {
  ParamCovariance C;
  for (int i = 0; i < ParamSet::kSize; ++i)
    for (int j = 0; j < ParamSet::kSize; ++j)
      C(i, j) = P(state_index_of_param(i), state_index_of_param(j));
  return C;
}

/// Write a ParamSet-ordered vector into the sensor part of a state vector.
inline void params_to_sensor_states(const ParamVector& p, StateVec& x) {
  for (int i = 0; i < ParamSet::kSize; ++i) x(state_index_of_param(i)) = p(i);
}

/// Where the navigation error dynamics are linearised (the nominal INS state over a short
/// propagation interval).
struct NavLinearisation {
  double lat_rad = 0.0;
  double height_m = 0.0;
  Eigen::Vector3d v_n_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d f_n_mps2 = Eigen::Vector3d::Zero();  ///< specific force in n (interval mean)
  double dg_dh_per_s2 = 0.0;                           ///< gravity gradient d|g|/dh (negative)
};

/// F_nn: the 9x9 navigation error dynamics of paper eq. 6-8 (sensor terms excluded).
NavMat nav_error_dynamics(const NavLinearisation& lin);

/// Integrates the sensor-to-navigation coupling F_ns (eq. 22 and 27) sample by sample over one
/// propagation interval, so the 36x36 transition matrix is formed once per interval rather than
/// at the IMU rate:  Φ_ns = ∫ Φ_nn(T - t) F_ns(t) dt  ≈  J0 + F_nn J1 + ½ F_nn² J2  with
/// J0 = ∫ F_ns dt, J1 = ∫ (T - t) F_ns dt, J2 = ∫ (T - t)² F_ns dt ≈ (2T/3) J1 (exact for constant
/// F_ns; F_nn³ is Earth-rate sized).
///
/// F_ns is C (I + M̂)^-1 [I3 dt, I3 incr_x, I3 incr_y, I3 incr_z] per sample (C the attitude,
/// incr = dθ or dv): (I + M̂)^-1 is constant in a pass and the rest is linear in C, so a sample
/// only adds C times eight scalar weights (four increments, with and without the sample time) —
/// one rank-one update per triad; the constant factors are applied once per interval.
class SensorCouplingAccumulator {
 public:
  SensorCouplingAccumulator() { reset(); }
  void reset();
  /// One IMU sample. C_bn_start/C_bn_end: nominal attitude at the start and end of the sample;
  /// dtheta_rad/dv_mps: *compensated* increments.
  void add(const Eigen::Matrix3d& C_bn_start, const Eigen::Matrix3d& C_bn_end,
           const Eigen::Vector3d& dtheta_rad, const Eigen::Vector3d& dv_mps, double dt_s);
  double duration_s() const { return T_s_; }
  bool empty() const { return T_s_ <= 0.0; }
  /// Mean specific force in n over the interval (Σ C_bn dv / T).
  Eigen::Vector3d mean_f_n_mps2() const;
  /// Φ_ns of the interval given the interval's F_nn and F_nn², and Ag_inv/Aa_inv =
  /// (I + M̂_g)^-1, (I + M̂_a)^-1 of the pass.
  NavSensorMat transition(const NavMat& F_nn, const NavMat& F_nn2, const Eigen::Matrix3d& Ag_inv,
                          const Eigen::Matrix3d& Aa_inv) const;

 private:
  // Row j: Σ w_j vec(C)ᵀ, row 4 + j: Σ t_mid w_j vec(C)ᵀ, w = (dt, incr_x, incr_y, incr_z), t_mid
  // from the interval start; columns: C column-major. Gyro: C the mid-sample attitude (an error in
  // dθ acts over the whole sample), accel: C at the sample start (dv is in the body frame there).
  using Moments = Eigen::Matrix<double, 8, 9>;
  /// Only two blocks of F_ns are non-zero: gyro states -> ψ rows, accel states -> δv rows, each
  /// 3 x 12 ([bias | dM column 0 | column 1 | column 2]).
  using Block = Eigen::Matrix<double, 3, 12>;
  /// The 3 x 12 block Σ (T - t)^m F_ns dt (m = 0, 1) from the sums.
  Block coupling(const Moments& S, int m, const Eigen::Matrix3d& A_inv) const;
  Moments S_g_, S_a_;
  double T_s_ = 0.0;
};

/// The block-triangular transition of the full state, Φ = [[Φ_nn, Φ_ns], [0, I]] (the sensor
/// states are random constants), and process noise Q on the navigation block only:
/// P <- Φ P Φ^T + Q computed blockwise (used identically by the filter and the RTS smoother).
void propagate_covariance(const NavMat& Phi_nn, const NavSensorMat& Phi_ns, const NavMat& Q,
                          const StateCov& P, StateCov& P_out);

/// Φ_nn = exp(F T) by a third-order series (|F T| is nilpotent-dominated: ψ→δv→δp; the remaining
/// entries are Earth-rate and gravity-gradient sized, so the series error is < 1e-9).
NavMat nav_transition(const NavMat& F_nn, double T_s);

}  // namespace imucal::calib::ains
