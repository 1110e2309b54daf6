#pragma once
// The table as it really is (ARCHITECTURE §7 table effects): the nominal two-axis geometry of
// calib/core/table_model.hpp with the inner axis leaning towards the outer one
// (table_nonorthogonality) and the platform tilting once per revolution (table_wobble):
//   C_bn = C_tn R(a_outer, outer) exp([δ_o(inner)×]) R(a_inner', inner) C_bp.
// With both zero this is TableModel::C_bn.
#include "calib/core/table_model.hpp"
#include "calib/effects/table_nonorthogonality.hpp"
#include "calib/effects/table_wobble.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

template <typename T>
Mat3<T> table_C_bn(const TableGeometry& g, double outer_rad, double inner_rad, const T& nonorth_rad,
                   const Eigen::Matrix<T, 2, 1>& wobble_rad) {
  const Eigen::Vector3d a_o = g.outer_axis_t.normalized();
  const Eigen::Vector3d a_i = g.inner_axis_o.normalized();
  const Mat3<double> C_tn = axis_angle(Eigen::Vector3d::UnitZ(), g.heading_rad);
  const Mat3<double> C_ot = axis_angle(a_o, outer_rad);
  // The outer axis is fixed in the outer-gimbal frame too (same vector there).
  const Vec3<T> a_i_true = nonorthogonal_inner_axis<T>(a_i, a_o, nonorth_rad);
  const Mat3<T> C_po = rotvec_to_matrix<T>(Vec3<T>(a_i_true * T(inner_rad)));
  const Mat3<T> tilt = rotvec_to_matrix<T>(wobble_tilt_o<T>(a_i, a_o, wobble_rad, inner_rad));
  return (C_tn * C_ot).cast<T>() * tilt * C_po * g.C_bp.cast<T>();
}

}  // namespace imucal::calib::effects
