#pragma once
// NLSQ residual blocks (paper eq. 50, restructured into uncorrelated blocks and, by default,
// extended by the table heading, as described in calib/nlsq/nlsq.hpp): thin Ceres autodiff adapters
// over the shared error model (eq. 18, 23) and the shared rotation helpers. Parameter blocks, in
// ParamSet's flat order:
//   b_a[3], dM_a[9] (row-major), b_g[3], dM_g[9] (row-major), ς[3].
#include <Eigen/Core>
#include <Eigen/LU>
#include <cmath>

#include "calib/core/imu_error_model.hpp"
#include "calib/core/rotation.hpp"
#include "calib/nlsq/nlsq_preprocess.hpp"

namespace imucal::calib::nlsq {
using namespace calib::core;

/// Accelerometer part of the error model from raw parameter-block pointers.
template <typename T>
ImuErrorModel<T> nlsq_accel_model(const T* b_a, const T* M_a_rowmajor) {
  ImuErrorModel<T> m;
  m.b_a = Eigen::Map<const Eigen::Matrix<T, 3, 1>>(b_a);
  m.M_a = Eigen::Map<const Eigen::Matrix<T, 3, 3, Eigen::RowMajor>>(M_a_rowmajor);
  return m;
}

/// C_bn_true = exp([ς×]) C_bn_ref (paper eq. 30-31).
template <typename T>
Mat3<T> nlsq_true_attitude(const T* varsigma, const Eigen::Matrix3d& C_bn_ref) {
  const Vec3<T> s = Eigen::Map<const Vec3<T>>(varsigma);
  return rotvec_to_matrix<T>(s) * C_bn_ref.cast<T>();
}

/// Compensated mean specific force of a rest, body axes: inverts
///   f_meas = (I + dM_a)(I + h1 [ω×] + h2 [ω×]²) f + b_a   (see NlsqRestMean)
/// with ω = ω_ib_b = C_bn_trueᵀ ω_ie_n at rest.
template <typename T>
Vec3<T> nlsq_rest_specific_force_b(const NlsqRestMean& rest, const ImuErrorModel<T>& em,
                                   const Mat3<T>& C_bn_true, const Eigen::Vector3d& w_ie_n) {
  const Vec3<T> y = em.compensate_dv(rest.f_meas_b.cast<T>(), T(1));  // eq. 18 inverse, per second
  const Vec3<T> w_ib_b = C_bn_true.transpose() * w_ie_n.cast<T>();
  const Mat3<T> W = skew<T>(w_ib_b);
  const Mat3<T> K = Mat3<T>::Identity() + T(rest.h1_s) * W + T(rest.h2_s2) * W * W;
  return K.inverse() * y;
}

/// a_R = C_bn_true(R) f(R) + g_n, whitened by the rest mean's σ (first block of eq. 50).
struct NlsqAccelRestResidual {
  NlsqRestMean rest;
  Eigen::Vector3d w_ie_n;
  Eigen::Vector3d g_n;

  template <typename T>
  bool operator()(const T* b_a, const T* M_a, const T* varsigma, T* residual) const {
    const ImuErrorModel<T> em = nlsq_accel_model(b_a, M_a);
    const Mat3<T> C_bn = nlsq_true_attitude(varsigma, rest.C_bn_ref);
    const Vec3<T> f_b = nlsq_rest_specific_force_b(rest, em, C_bn, w_ie_n);
    const Vec3<T> r = (C_bn * f_b + g_n.cast<T>()) / T(rest.sigma_f_mps2);
    for (int i = 0; i < 3; ++i) residual[i] = r(i);
    return true;
  }
};

/// Gyro-propagated attitude of rest B: Ĉ_bn(B) = E_n C_bn_true(A) ΔC_b(θ), with ΔC_b linearised in
/// the gyro parameters θ_g = (b_g, dM_g row-major) around θ_g0 (NlsqRotation).
template <typename T>
Mat3<T> nlsq_propagated_attitude(const NlsqRotation& rot, const Mat3<T>& C_bn_true_a, const T* b_g,
                                 const T* M_g) {
  Eigen::Matrix<T, 12, 1> dtheta_g;
  for (int i = 0; i < 3; ++i) dtheta_g(i) = b_g[i] - T(rot.theta_g0(i));
  for (int i = 0; i < 9; ++i) dtheta_g(3 + i) = M_g[i] - T(rot.theta_g0(3 + i));
  const Vec3<T> dphi_b = rot.J_b.cast<T>() * dtheta_g;
  const Mat3<T> dC_b = rot.dC_b0.cast<T>() * rotvec_to_matrix<T>(dphi_b);
  return rot.E_n.cast<T>() * C_bn_true_a * dC_b;
}

/// log(R) for a rotation R of angle well below π (Jet-safe): θ/sin θ · vee(R - Rᵀ)/2. The attitude
/// residuals it is used for are at most a few milliradians (the misfit of the start values).
template <typename T>
Vec3<T> nlsq_rotation_log(const Mat3<T>& R) {
  using std::atan2;
  using std::sqrt;
  const Vec3<T> w(T(0.5) * (R(2, 1) - R(1, 2)), T(0.5) * (R(0, 2) - R(2, 0)),
                  T(0.5) * (R(1, 0) - R(0, 1)));  // sin θ · axis
  const T s2 = w.squaredNorm();
  const T c = T(0.5) * (R.trace() - T(1));  // cos θ
  if (s2 < T(1e-10)) {
    // θ/sin θ = 1 + s²/6 + 3s⁴/40 + ... for cos θ > 0; error below 1e-16 relative here.
    return (T(1) + s2 / T(6) + T(3) * s2 * s2 / T(40)) * w;
  }
  const T s = sqrt(s2);
  return (atan2(s, c) / s) * w;
}

/// Full attitude residual of a gyro propagation span (NlsqOptions::use_table_heading, the
/// default): the table's attitude at the end of the span against the gyro-propagated one,
///   ψ = log(C_bn_true(B) Ĉ_bn(B)ᵀ),  Ĉ_bn(B) = E_n C_bn_true(A) ΔC_b(θ),
/// i.e. the psi-convention error Ĉ = (I - [ψ×]) C. For a rotation, ψ's horizontal part times g is
/// eq. 50's second block minus the table-attitude residual of rest B (d_i below); its vertical part
/// is the heading error, which a precision table measures too. For a whole rest (A = B) it says
/// that the compensated gyros reproduce the Earth rate while the table holds still. Noise: the
/// propagation's angle noise, isotropic σ_psi. Independent of the accelerometer parameters.
struct NlsqAttitudeResidual {
  NlsqRestMean rest_a;
  NlsqRestMean rest_b;
  NlsqRotation rot;

  template <typename T>
  bool operator()(const T* b_g, const T* M_g, const T* varsigma, T* residual) const {
    const Mat3<T> C_bn_a = nlsq_true_attitude(varsigma, rest_a.C_bn_ref);
    const Mat3<T> C_bn_b = nlsq_true_attitude(varsigma, rest_b.C_bn_ref);
    const Mat3<T> C_bn_b_gyro = nlsq_propagated_attitude(rot, C_bn_a, b_g, M_g);
    const Vec3<T> psi = nlsq_rotation_log<T>(Mat3<T>(C_bn_b * C_bn_b_gyro.transpose()));
    const T scale = T(1.0 / rot.sigma_psi_rad);
    for (int i = 0; i < 3; ++i) residual[i] = psi(i) * scale;
    return true;
  }
};

/// d_i = (Ĉ_bn(B) - C_bn_true(B)) f(B): the second block of eq. 50 minus the table-attitude
/// residual of rest B. Ĉ_bn(B) = E_n C_bn_true(A) ΔC_b(θ), with ΔC_b linearised in the gyro
/// parameters (NlsqRotation). Noise: ψ (isotropic, σ_psi) shows as d ≈ ψ × g_n, i.e. |f| σ_psi on
/// the two horizontal components; the vertical one is second order and not used. This is the
/// paper's gravity-only form (NlsqOptions::use_table_heading = false).
struct NlsqRotationResidual {
  NlsqRestMean rest_a;
  NlsqRestMean rest_b;
  NlsqRotation rot;
  Eigen::Vector3d w_ie_n;

  template <typename T>
  bool operator()(const T* b_a, const T* M_a, const T* b_g, const T* M_g, const T* varsigma,
                  T* residual) const {
    const Mat3<T> C_bn_a = nlsq_true_attitude(varsigma, rest_a.C_bn_ref);
    const Mat3<T> C_bn_b = nlsq_true_attitude(varsigma, rest_b.C_bn_ref);
    const Mat3<T> C_bn_b_gyro = nlsq_propagated_attitude(rot, C_bn_a, b_g, M_g);

    const ImuErrorModel<T> em = nlsq_accel_model(b_a, M_a);
    const Vec3<T> f_b = nlsq_rest_specific_force_b(rest_b, em, C_bn_b, w_ie_n);
    const Vec3<T> d = (C_bn_b_gyro - C_bn_b) * f_b;
    const T scale = T(1.0 / (rest_b.f_meas_b.norm() * rot.sigma_psi_rad));
    residual[0] = d(0) * scale;
    residual[1] = d(1) * scale;
    return true;
  }
};

}  // namespace imucal::calib::nlsq
