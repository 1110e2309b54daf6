#pragma once
// table_wobble (ARCHITECTURE §7): a once-per-revolution tilt of the platform against the outer
// gimbal. A first-harmonic tilt δ_o(θ) = A cos θ + B sin θ (perpendicular to the inner axis) splits
// into a part turning with the platform, which is a fixed mounting rotation (absorbed by the
// misalignments, never observable), and a part turning against it: δ_o(θ) = R(a_inner, -θ) w,
// w = w_x u1 + w_y u2, u1 = the outer axis' component perpendicular to the inner axis, u2 = a_inner
// × u1 (default geometry: Rz(-θ) (w_x, w_y, 0)). The platform is C_op = exp([δ_o×]) R(a_inner, θ).
#include "calib/core/rotation.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// Tilt rotation vector of the platform in the outer-gimbal frame at inner angle `inner_rad`.
template <typename T>
Vec3<T> wobble_tilt_o(const Eigen::Vector3d& inner_o, const Eigen::Vector3d& outer_o,
                      const Eigen::Matrix<T, 2, 1>& w_rad, double inner_rad) {
  const Eigen::Vector3d a = inner_o.normalized();
  const Eigen::Vector3d u1 = (outer_o - outer_o.dot(a) * a).normalized();
  const Eigen::Vector3d u2 = a.cross(u1);
  const Eigen::Matrix3d R = rotvec_to_matrix<double>(Eigen::Vector3d(-inner_rad * a));
  return (R * u1).cast<T>() * w_rad(0) + (R * u2).cast<T>() * w_rad(1);
}

}  // namespace imucal::calib::effects
