#pragma once
// The table's kinematics as altsim derives them: the true body attitude from the encoder angles
// (with the table's imperfections and ς), and the body rate and angular acceleration from the
// gimbal rates — not by differencing attitudes. The chain (b to n):
//   C_bn = C_ς C_tn · A_o(θo) · T(δ(θi)) · A_i(θi) · C_bp
// A_o = rotation about the outer axis a_o, T = exp([δ×]) the wobble tilt, A_i = rotation about the
// (possibly leaning) inner axis a_i'. For C = A1 A2 ... A5, C^T Ċ = Σ_k (A_{k+1}..A5)^T
// (A_k^T Ȧ_k) (A_{k+1}..A5), and a rotation about a fixed axis a by θ has A^T Ȧ = θ̇ [a×], so
//   ω_nb_b = C_bp^T ( A_i^T ( T^T θ̇o a_o + ω_T ) + θ̇i a_i' ),   ω_T = J_r(δ) δ̇,
// with J_r the right Jacobian of SO(3) and δ̇ = -θ̇i a_i × δ (δ = R(a_i, -θi) w turns against the
// platform). The Earth turns n: ω_ib_b = ω_nb_b + C_bn^T ω_ie_n.
#include <Eigen/Core>

#include "sequences/motion_profile.hpp"
#include "tools/altsim/alt_sim.hpp"

namespace imucal::tools::altsim {

/// [v×]: skew(v) * u == v.cross(u).
Eigen::Matrix3d skew3(const Eigen::Vector3d& v);
/// Rotation by angle_rad about the unit axis (Rodrigues' formula).
Eigen::Matrix3d rotation_about(const Eigen::Vector3d& axis_unit, double angle_rad);
/// exp([φ×]) for a rotation vector φ.
Eigen::Matrix3d rotation_from_vector(const Eigen::Vector3d& phi_rad);

/// Both axes' angle, rate and acceleration at t, from the segment's own quadratic (also slightly
/// outside the segment: the integrator evaluates a piece's ends with the piece's segment, so that
/// an acceleration jump at a breakpoint never leaks into the neighbouring piece).
sequences::TableState state_in_segment(const sequences::ProfileSegment& seg, double t_s);

/// What the integrator needs at one instant.
struct BodyKinematics {
  Eigen::Matrix3d C_bn = Eigen::Matrix3d::Identity();   ///< true attitude, b to n
  Eigen::Vector3d w_ib_b = Eigen::Vector3d::Zero();     ///< body rate w.r.t. inertial, rad/s
  Eigen::Vector3d wdot_ib_b = Eigen::Vector3d::Zero();  ///< its derivative (if asked), rad/s²
  Eigen::Vector3d f_b = Eigen::Vector3d::Zero();        ///< specific force at the centre, m/s²
};

class TableKinematics {
 public:
  /// `site` is the TRUE site (the site errors already applied by the caller).
  TableKinematics(const AltTable& table, const AltEffects& effects, double true_lat_rad,
                  double true_gravity_mps2, double earth_rate_radps);

  /// Attitude, rates and specific force for the table state s (wdot_ib_b only if with_wdot).
  BodyKinematics at(const sequences::TableState& s, bool with_wdot) const;
  /// The true body attitude for encoder angles (outer, inner).
  Eigen::Matrix3d C_bn(double outer_rad, double inner_rad) const;
  const Eigen::Vector3d& w_ie_n() const { return w_ie_n_; }

 private:
  Eigen::Vector3d wobble_o(double inner_rad) const;

  Eigen::Matrix3d C_left_;  ///< C_ς C_tn: constant part left of the outer rotation
  Eigen::Matrix3d C_bp_;
  Eigen::Vector3d a_o_, a_i_, a_i_lean_;  ///< outer axis, nominal and leaning inner axis
  Eigen::Vector3d u1_, u2_;               ///< wobble basis (perpendicular to a_i)
  Eigen::Vector2d wobble_rad_;
  bool wobble_ = false;
  Eigen::Vector3d w_ie_n_, f_n_;
};

}  // namespace imucal::tools::altsim
