#include "calib/ains/ains_model.hpp"

#include <cmath>

#include "calib/core/rotation.hpp"

namespace imucal::calib::ains {
using namespace calib::core;

using Eigen::Matrix3d;
using Eigen::Vector3d;

NavMat nav_error_dynamics(const NavLinearisation& lin) {
  const double Om = wgs84::kEarthRate_radps;
  const double sL = std::sin(lin.lat_rad), cL = std::cos(lin.lat_rad);
  const double RNh = EarthModel::radius_north_m(lin.lat_rad) + lin.height_m;
  const double REh = EarthModel::radius_east_m(lin.lat_rad) + lin.height_m;
  const Vector3d w_ie_n = EarthModel::w_ie_n_at(lin.lat_rad);
  const Vector3d w_en_n = EarthModel::w_en_n(lin.v_n_mps, lin.lat_rad, lin.height_m);
  const Vector3d w_in_n = w_ie_n + w_en_n;

  // ∂ω_en/∂δv (transport rate, EarthModel::w_en_n) and ∂ω_ie/∂δp_N (latitude error δp_N / R_N).
  Matrix3d dwen_dv = Matrix3d::Zero();
  dwen_dv(0, 1) = 1.0 / REh;
  dwen_dv(1, 0) = -1.0 / RNh;
  dwen_dv(2, 1) = -std::tan(lin.lat_rad) / REh;
  const Vector3d dwie_dpN = Vector3d(-Om * sL, 0.0, -Om * cL) / RNh;

  NavMat F = NavMat::Zero();
  // eq. 6: δψ̇ = -ω_in x ψ + δω_in (- C δω_ib: sensor block, see SensorCouplingAccumulator)
  F.block<3, 3>(kPsi, kPsi) = -skew<double>(w_in_n);
  F.block<3, 3>(kPsi, kVel) = dwen_dv;
  F.block<3, 1>(kPsi, kPos) = dwie_dpN;
  // eq. 7: δv̇ = [f_n x] ψ - (2ω_ie + ω_en) x δv - (2δω_ie + δω_en) x v + (ĝ - g)
  F.block<3, 3>(kVel, kPsi) = skew<double>(lin.f_n_mps2);
  F.block<3, 3>(kVel, kVel) =
      -skew<double>(2.0 * w_ie_n + w_en_n) + skew<double>(lin.v_n_mps) * dwen_dv;
  F.block<3, 1>(kVel, kPos) = skew<double>(lin.v_n_mps) * (2.0 * dwie_dpN);
  // ĝ - g = dg/dh (ĥ - h) = -dg/dh δp_D: the unstable vertical channel (depth aiding, eq. 40-43).
  F(kVel + 2, kPos + 2) = -lin.dg_dh_per_s2;
  // eq. 8: δṗ = δv (NED metres)
  F.block<3, 3>(kPos, kVel) = Matrix3d::Identity();
  return F;
}

NavMat nav_transition(const NavMat& F_nn, double T_s) {
  // lazyProduct: coefficient-based products; Eigen's blocked GEMM path costs more than the
  // arithmetic for matrices this small.
  const NavMat A = F_nn * T_s;
  const NavMat A2 = A.lazyProduct(A);
  const NavMat A3 = A2.lazyProduct(A);
  return NavMat::Identity() + A + 0.5 * A2 + (1.0 / 6.0) * A3;
}

void propagate_covariance(const NavMat& Phi_nn, const NavSensorMat& Phi_ns, const NavMat& Q,
                          const StateCov& P, StateCov& P_out) {
  constexpr int kNs = kNumSensor;
  const auto Pnn = P.topLeftCorner<kNumNav, kNumNav>();
  const auto Pns = P.topRightCorner<kNumNav, kNs>();
  const auto Pss = P.bottomRightCorner<kNs, kNs>();
  // Φ_ns's ς columns are zero (ς does not drive the navigation errors): 24 of its 27 columns.
  constexpr int kDriven = kTableMis - kNumNav;
  const auto Phi_nd = Phi_ns.leftCols<kDriven>();
  NavSensorMat Pns_new;
  Pns_new.noalias() = Phi_nd * Pss.topRows<kDriven>();
  Pns_new.noalias() += Phi_nn.lazyProduct(Pns);
  const NavMat M =
      Phi_nn.lazyProduct(Pnn) + Phi_nd.lazyProduct(Pns.leftCols<kDriven>().transpose());
  NavMat Pnn_new = M.lazyProduct(Phi_nn.transpose()) +
                   Pns_new.leftCols<kDriven>().lazyProduct(Phi_nd.transpose()) + Q;
  P_out.topLeftCorner<kNumNav, kNumNav>() = 0.5 * (Pnn_new + Pnn_new.transpose());
  P_out.topRightCorner<kNumNav, kNs>() = Pns_new;
  P_out.bottomLeftCorner<kNs, kNumNav>() = Pns_new.transpose();
  if (&P_out != &P) P_out.bottomRightCorner<kNs, kNs>() = Pss;
}

void SensorCouplingAccumulator::reset() {
  S_g_.setZero();
  S_a_.setZero();
  T_s_ = 0.0;
}

void SensorCouplingAccumulator::add(const Matrix3d& C_bn_start, const Matrix3d& C_bn_end,
                                    const Vector3d& dtheta_rad, const Vector3d& dv_mps,
                                    double dt_s) {
  // eq. 27 (× dt, ω dt = dθ): ∂ψ/∂(Δb_g, ΔM_g) = -C_bn (I+M̂_g)^-1 [I3 dt, I3 dθ_x, I3 dθ_y, I3
  // dθ_z] eq. 22 (× dt, f dt = dv): ∂δv/∂(Δb_a, ΔM_a) = C_bn (I+M̂_a)^-1 [I3 dt, I3 dv_x, I3 dv_y,
  // I3 dv_z] The gyro rows use the mid-sample attitude (mean of both ends, second-order accurate).
  const double t_mid = T_s_ + 0.5 * dt_s;
  Eigen::Matrix<double, 8, 1> w_g, w_a;
  w_g.head<4>() << dt_s, dtheta_rad;
  w_a.head<4>() << dt_s, dv_mps;
  w_g.head<4>() *= -0.5;
  w_g.tail<4>() = t_mid * w_g.head<4>();
  w_a.tail<4>() = t_mid * w_a.head<4>();
  // Rank-one updates column by column (Eigen's generic outer product did not inline here).
  for (int i = 0; i < 9; ++i) {
    S_g_.col(i) += w_g * (C_bn_start.data()[i] + C_bn_end.data()[i]);
    S_a_.col(i) += w_a * C_bn_start.data()[i];
  }
  T_s_ += dt_s;
}

Vector3d SensorCouplingAccumulator::mean_f_n_mps2() const {
  if (!(T_s_ > 0.0)) return Vector3d::Zero();
  // Σ C dv = Σ_c (Σ dv_c C) e_c: column c of the sum of weight dv_c.
  Vector3d sum_C_dv = Vector3d::Zero();
  for (int c = 0; c < 3; ++c)
    sum_C_dv +=
        Eigen::Map<const Matrix3d>(Eigen::Matrix<double, 1, 9>(S_a_.row(1 + c)).data()).col(c);
  return sum_C_dv / T_s_;
}

SensorCouplingAccumulator::Block SensorCouplingAccumulator::coupling(const Moments& S, int m,
                                                                     const Matrix3d& A_inv) const {
  // m = 0: Σ w_j C; m = 1: Σ (T - t) w_j C = T Σ w_j C - Σ t w_j C; then times A_inv.
  const Eigen::Matrix<double, 4, 9> rows =
      m == 0 ? Eigen::Matrix<double, 4, 9>(S.topRows<4>())
             : Eigen::Matrix<double, 4, 9>(T_s_ * S.topRows<4>() - S.bottomRows<4>());
  Block J;
  for (int j = 0; j < 4; ++j)
    J.middleCols<3>(3 * j) =
        Eigen::Map<const Matrix3d>(Eigen::Matrix<double, 1, 9>(rows.row(j)).data()) * A_inv;
  return J;
}

NavSensorMat SensorCouplingAccumulator::transition(const NavMat& F_nn, const NavMat& F2,
                                                   const Matrix3d& Ag_inv,
                                                   const Matrix3d& Aa_inv) const {
  // Φ_ns = J0 + F J1 + ½ F² J2; only the ψ/gyro and δv/accel blocks of J are non-zero, so only
  // F's ψ and δv columns are needed.
  constexpr int ba = kAccBias - kNumNav, bg = kGyroBias - kNumNav;
  NavSensorMat Phi = NavSensorMat::Zero();
  // J2 ≈ (2T/3) J1, exact for constant F_ns: the exact second moment changed no estimate by
  // 1e-4 σ on an hour of table data with 1 s sub-intervals, and costs half as much again per
  // sample.
  const Block J1_g = coupling(S_g_, 1, Ag_inv), J1_a = coupling(S_a_, 1, Aa_inv);
  const double c2 = T_s_ / 3.0;  // ½ · 2T/3
  Phi.middleCols<12>(bg) =
      (F_nn.middleCols<3>(kPsi) + c2 * F2.middleCols<3>(kPsi)).lazyProduct(J1_g);
  Phi.middleCols<12>(ba) =
      (F_nn.middleCols<3>(kVel) + c2 * F2.middleCols<3>(kVel)).lazyProduct(J1_a);
  Phi.block<3, 12>(kPsi, bg) += coupling(S_g_, 0, Ag_inv);
  Phi.block<3, 12>(kVel, ba) += coupling(S_a_, 0, Aa_inv);
  return Phi;
}

}  // namespace imucal::calib::ains
