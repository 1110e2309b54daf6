#include "calib/core/table_model.hpp"

#include "calib/core/rotation.hpp"

namespace imucal::calib::core {

TableModel::TableModel(const TableGeometry& g) : g_(g) {
  g_.outer_axis_t.normalize();
  g_.inner_axis_o.normalize();
  C_tn_ = axis_angle(Eigen::Vector3d::UnitZ(), g_.heading_rad);
}

Eigen::Matrix3d TableModel::C_bn(double outer_rad, double inner_rad) const {
  // C_bn = C_tn C_ot C_po C_bp: base -> outer gimbal -> platform -> body (fixture).
  return C_tn_ * axis_angle(g_.outer_axis_t, outer_rad) * axis_angle(g_.inner_axis_o, inner_rad) *
         g_.C_bp;
}

Eigen::Vector3d TableModel::w_nb_b(const sequences::TableState& s) const {
  // The outer axis is fixed in both the base and the outer-gimbal frame; the inner axis in both the
  // outer-gimbal and the platform frame.
  const Eigen::Matrix3d C_op = axis_angle(g_.inner_axis_o, -s.inner_rad);
  const Eigen::Vector3d w_tp_p =
      C_op * (s.outer_rate_radps * g_.outer_axis_t) + s.inner_rate_radps * g_.inner_axis_o;
  return g_.C_bp.transpose() * w_tp_p;
}

Eigen::Vector3d TableModel::wdot_nb_b(const sequences::TableState& s) const {
  const Eigen::Matrix3d C_op = axis_angle(g_.inner_axis_o, -s.inner_rad);
  const Eigen::Vector3d outer_p = C_op * g_.outer_axis_t;
  // d/dt C_op = -inner_rate [a_i x] C_op.
  const Eigen::Vector3d wdot_p =
      -s.inner_rate_radps * g_.inner_axis_o.cross(outer_p) * s.outer_rate_radps +
      s.outer_accel_radps2 * outer_p + s.inner_accel_radps2 * g_.inner_axis_o;
  return g_.C_bp.transpose() * wdot_p;
}

}  // namespace imucal::calib::core
