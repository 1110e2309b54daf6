#pragma once
// Two-axis turntable geometry: what the table's encoder angles say about the body attitude.
//   C_bn_table(outer, inner) = C_tn * R(a_outer, outer) * R(a_inner, inner) * C_bp
// t = table base frame (levelled, rotated by heading_rad about down), p = platform frame,
// b = IMU housing frame mounted on the platform by the fixture (C_bp: b to p).
// The true attitude adds the table misalignment ς: C_bn_true = exp([ς x]) C_bn_table.
//
// DEFAULT GEOMETRY (the usual IMU-calibration two-axis table): the OUTER axis is HORIZONTAL, along
// the base frame's x (north at heading 0); the INNER axis is the platform normal, which is vertical
// (down) at outer = 0. The body frame coincides with the platform frame (C_bp = I). Hence:
//   inner rotations always turn about body z;
//   outer rotations turn about body x at inner = 0, about body -y at inner = 90°, ...;
//   outer = 180° puts body z up; inner = 90° then outer = ±90° puts body x down/up; inner = 0 then
//   outer = ±90° puts body y up/down.
// (A vertical outer axis cannot calibrate: the body axis along a horizontal inner axis would never
// see gravity.)
#include <Eigen/Core>

#include "sequences/motion_profile.hpp"

namespace imucal::calib::core {

/// How far inside a table's rest segment its at_rest flag begins and ends (s): the simulator
/// flags rest this way and the CRLB places its aiding epochs the same, so both see the same epochs.
constexpr double kTableRestGuard_s = 0.5;

struct TableGeometry {
  Eigen::Vector3d outer_axis_t{1.0, 0.0,
                               0.0};  ///< outer axis in the base frame (default: horizontal)
  Eigen::Vector3d inner_axis_o{0.0, 0.0,
                               1.0};  ///< inner axis in the outer-gimbal frame (platform normal)
  double heading_rad = 0.0;           ///< base-frame heading: C_tn = Rz(heading)
  Eigen::Matrix3d C_bp = Eigen::Matrix3d::Identity();  ///< fixture: body to platform
};

class TableModel {
 public:
  explicit TableModel(const TableGeometry& g);
  const TableGeometry& geometry() const { return g_; }

  /// Attitude the table reports for the given encoder angles (no misalignment ς).
  Eigen::Matrix3d C_bn(double outer_rad, double inner_rad) const;
  /// Body rate w.r.t. the n-frame, in body axes, for the given axis angles and rates.
  Eigen::Vector3d w_nb_b(const sequences::TableState& s) const;
  /// Body angular acceleration w.r.t. n, in body axes (for the size effect).
  Eigen::Vector3d wdot_nb_b(const sequences::TableState& s) const;

 private:
  TableGeometry g_;
  Eigen::Matrix3d C_tn_;
};

}  // namespace imucal::calib::core
