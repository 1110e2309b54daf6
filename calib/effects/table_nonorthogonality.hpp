#pragma once
// table_nonorthogonality (ARCHITECTURE §7): the table's inner axis is not at 90° to its outer axis.
// It leans towards the outer axis by δ: rotated about n = a_inner × a_outer (normalised) by δ in
// the outer-gimbal frame (default geometry: inner = Ry(δ) e_z, 90° - δ from the outer axis x). A
// lean about the outer axis itself is not modelled: it is a table misalignment ς plus a fixed
// mounting rotation, which the calibration absorbs.
#include "calib/core/rotation.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// The inner axis (outer-gimbal frame) leaning by delta towards the outer axis.
template <typename T>
Vec3<T> nonorthogonal_inner_axis(const Eigen::Vector3d& inner_o, const Eigen::Vector3d& outer_o,
                                 const T& delta_rad) {
  const Eigen::Vector3d n = inner_o.cross(outer_o).normalized();
  return rotvec_to_matrix<T>(Vec3<T>(n.cast<T>() * delta_rad)) * inner_o.cast<T>();
}

}  // namespace imucal::calib::effects
