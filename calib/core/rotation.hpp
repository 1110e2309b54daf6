#pragma once
// Rotation helpers, templated on the scalar so Ceres Jets can pass through them.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

namespace imucal::calib::core {

template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;

/// [v x]: the cross-product matrix, skew(a) * b == a.cross(b).
template <typename T>
Mat3<T> skew(const Vec3<T>& v) {
  Mat3<T> S;
  S << T(0), -v(2), v(1), v(2), T(0), -v(0), -v(1), v(0), T(0);
  return S;
}

/// exp([phi x]): rotation matrix of rotation vector phi (Rodrigues). Series near zero keeps Jets
/// finite and double precision at 1e-16 for the tiny angles of increments.
template <typename T>
Mat3<T> rotvec_to_matrix(const Vec3<T>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta2 = phi.squaredNorm();
  T a, b;
  if (theta2 < T(1e-4)) {
    // Taylor series to θ^6: the first omitted terms are θ^8/362880 and θ^8/3628800, < 3e-22 here.
    // Covers every IMU increment at 100 Hz up to ~57 °/s without sin/cos/sqrt.
    const T t4 = theta2 * theta2;
    a = T(1) - theta2 / T(6) + t4 / T(120) - t4 * theta2 / T(5040);
    b = T(0.5) - theta2 / T(24) + t4 / T(720) - t4 * theta2 / T(40320);
  } else {
    const T theta = sqrt(theta2);
    a = sin(theta) / theta;
    b = (T(1) - cos(theta)) / theta2;
  }
  // I + a K + b K² with K² = φφᵀ - θ² I, element by element (a quarter of the arithmetic of the
  // matrix products: the strapdown, NLSQ and the evaluation call this once or twice per sample).
  const T c = T(1) - b * theta2;  // cos θ
  const T bx = b * phi(0), by = b * phi(1), bz = b * phi(2);
  const T ax = a * phi(0), ay = a * phi(1), az = a * phi(2);
  Mat3<T> R;
  R(0, 0) = c + bx * phi(0);
  R(1, 1) = c + by * phi(1);
  R(2, 2) = c + bz * phi(2);
  R(0, 1) = bx * phi(1) - az;
  R(1, 0) = bx * phi(1) + az;
  R(0, 2) = bx * phi(2) + ay;
  R(2, 0) = bx * phi(2) - ay;
  R(1, 2) = by * phi(2) - ax;
  R(2, 1) = by * phi(2) + ax;
  return R;
}

/// log(C): rotation vector of a rotation matrix (inverse of rotvec_to_matrix), angle < pi.
inline Eigen::Vector3d matrix_to_rotvec(const Eigen::Matrix3d& C) {
  const Eigen::Vector3d w(C(2, 1) - C(1, 2), C(0, 2) - C(2, 0), C(1, 0) - C(0, 1));
  const double s = 0.5 * w.norm();           // sin(theta)
  const double c = 0.5 * (C.trace() - 1.0);  // cos(theta)
  const double theta = std::atan2(s, c);
  if (theta < 1e-6) return 0.5 * (1.0 + theta * theta / 6.0) * w;  // theta/sin(theta) series
  if (theta < 3.1) return (theta / (2.0 * s)) * w;
  // Near pi: use the symmetric part.
  Eigen::Matrix3d B = 0.5 * (C + C.transpose()) - c * Eigen::Matrix3d::Identity();
  int i;
  B.diagonal().maxCoeff(&i);
  Eigen::Vector3d axis = B.col(i) / std::sqrt(std::max(B(i, i), 1e-300));
  axis.normalize();
  if (axis.dot(w) < 0) axis = -axis;
  return theta * axis;
}

/// Rotation matrix about a unit axis by angle (right-handed).
inline Eigen::Matrix3d axis_angle(const Eigen::Vector3d& axis_unit, double angle_rad) {
  return rotvec_to_matrix<double>(axis_unit * angle_rad);
}

/// C_bn from NED Euler angles (ZYX: yaw, then pitch, then roll), body w.r.t. n.
inline Eigen::Matrix3d euler_to_C_bn(double roll_rad, double pitch_rad, double yaw_rad) {
  return axis_angle(Eigen::Vector3d::UnitZ(), yaw_rad) *
         axis_angle(Eigen::Vector3d::UnitY(), pitch_rad) *
         axis_angle(Eigen::Vector3d::UnitX(), roll_rad);
}

/// Inverse of euler_to_C_bn: returns (roll, pitch, yaw) in rad.
inline Eigen::Vector3d C_bn_to_euler(const Eigen::Matrix3d& C_bn) {
  const double pitch = std::asin(std::clamp(-C_bn(2, 0), -1.0, 1.0));
  const double roll = std::atan2(C_bn(2, 1), C_bn(2, 2));
  const double yaw = std::atan2(C_bn(1, 0), C_bn(0, 0));
  return {roll, pitch, yaw};
}

/// Re-orthonormalise a DCM that accumulated round-off (one Newton step toward the polar factor;
/// enough because the error is at round-off level after each update).
inline Eigen::Matrix3d orthonormalize(const Eigen::Matrix3d& C) {
  return 1.5 * C - 0.5 * C * C.transpose() * C;
}

}  // namespace imucal::calib::core
