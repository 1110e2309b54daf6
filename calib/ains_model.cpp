#include "calib/ains_model.hpp"

#include <cmath>

#include "calib/rotation.hpp"

namespace imucal::calib::ains {

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
  const NavSensorMat Pns_new = Phi_nn.lazyProduct(Pns) + Phi_ns.lazyProduct(Pss);
  const NavMat M = Phi_nn.lazyProduct(Pnn) + Phi_ns.lazyProduct(Pns.transpose());
  NavMat Pnn_new = M.lazyProduct(Phi_nn.transpose()) + Pns_new.lazyProduct(Phi_ns.transpose()) + Q;
  P_out.topLeftCorner<kNumNav, kNumNav>() = 0.5 * (Pnn_new + Pnn_new.transpose());
  P_out.topRightCorner<kNumNav, kNs>() = Pns_new;
  P_out.bottomLeftCorner<kNs, kNumNav>() = Pns_new.transpose();
  if (&P_out != &P) P_out.bottomRightCorner<kNs, kNs>() = Pss;
}

void SensorCouplingAccumulator::reset() {
  J0_g_.setZero();
  J0_a_.setZero();
  J1t_g_.setZero();
  J1t_a_.setZero();
  sum_C_dv_.setZero();
  T_s_ = 0.0;
}

void SensorCouplingAccumulator::add(const Matrix3d& C_bn_start, const Matrix3d& C_bn_end,
                                    const Vector3d& dtheta_rad, const Vector3d& dv_mps, double dt_s,
                                    const Matrix3d& Ag_inv, const Matrix3d& Aa_inv) {
  // dv is expressed in the body frame at the sample start (conventions.hpp), so its error maps
  // through C_bn(start); an error in dθ acts on the attitude over the whole sample, so it maps
  // through the mid-sample attitude (mean of both ends, second-order accurate).
  const Matrix3d B_a = C_bn_start * Aa_inv;
  const Matrix3d B_g = -0.5 * (C_bn_start + C_bn_end) * Ag_inv;
  const double t_mid = T_s_ + 0.5 * dt_s;

  // eq. 27 (× dt, ω dt = dθ): ∂ψ/∂(Δb_g, ΔM_g) = -C_bn (I+M̂_g)^-1 [I3 dt, I3 dθ_x, I3 dθ_y, I3
  // dθ_z] eq. 22 (× dt, f dt = dv): ∂δv/∂(Δb_a, ΔM_a) = C_bn (I+M̂_a)^-1 [I3 dt, I3 dv_x, I3 dv_y,
  // I3 dv_z]
  auto accumulate = [&](Block& J0, Block& J1t, const Matrix3d& B, const Vector3d& incr) {
    J0.leftCols<3>() += B * dt_s;
    J1t.leftCols<3>() += B * (dt_s * t_mid);
    for (int c = 0; c < 3; ++c) {
      J0.middleCols<3>(3 + 3 * c) += B * incr(c);
      J1t.middleCols<3>(3 + 3 * c) += B * (incr(c) * t_mid);
    }
  };
  accumulate(J0_g_, J1t_g_, B_g, dtheta_rad);
  accumulate(J0_a_, J1t_a_, B_a, dv_mps);

  sum_C_dv_ += C_bn_start * dv_mps;
  T_s_ += dt_s;
}

Vector3d SensorCouplingAccumulator::mean_f_n_mps2() const {
  return T_s_ > 0.0 ? Vector3d(sum_C_dv_ / T_s_) : Vector3d::Zero();
}

NavSensorMat SensorCouplingAccumulator::transition(const NavMat& F_nn, const NavMat& F2) const {
  // Φ_ns = J0 + F J1 + (T/3) F² J1, with J1 = T J0 - Σ t F_ns dt; only the ψ/gyro and δv/accel
  // blocks of J are non-zero, so only F's ψ and δv columns are needed.
  constexpr int ba = kAccBias - kNumNav, bg = kGyroBias - kNumNav;
  const Eigen::Matrix<double, kNumNav, 3> Fg =
      F_nn.middleCols<3>(kPsi) + (T_s_ / 3.0) * F2.middleCols<3>(kPsi);
  const Eigen::Matrix<double, kNumNav, 3> Fa =
      F_nn.middleCols<3>(kVel) + (T_s_ / 3.0) * F2.middleCols<3>(kVel);
  NavSensorMat Phi = NavSensorMat::Zero();
  const Block J1_g = T_s_ * J0_g_ - J1t_g_, J1_a = T_s_ * J0_a_ - J1t_a_;
  Phi.middleCols<12>(bg) = Fg.lazyProduct(J1_g);
  Phi.middleCols<12>(ba) = Fa.lazyProduct(J1_a);
  Phi.block<3, 12>(kPsi, bg) += J0_g_;
  Phi.block<3, 12>(kVel, ba) += J0_a_;
  return Phi;
}

}  // namespace imucal::calib::ains
