#include "tools/altsim/alt_kinematics.hpp"

#include <cmath>

namespace imucal::tools::altsim {

Eigen::Matrix3d skew3(const Eigen::Vector3d& v) {
  Eigen::Matrix3d S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

Eigen::Matrix3d rotation_about(const Eigen::Vector3d& a, double angle_rad) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  return c * Eigen::Matrix3d::Identity() + s * skew3(a) + (1.0 - c) * a * a.transpose();
}

Eigen::Matrix3d rotation_from_vector(const Eigen::Vector3d& phi_rad) {
  const double a2 = phi_rad.squaredNorm();
  if (a2 < 1e-8) {
    // I + (sin a/a) K + ((1 - cos a)/a²) K², the coefficients to a²: the next terms are a⁴/120
    // and a⁴/720 < 1e-18 here (the table's arcsec tilts take this branch, without sin/cos).
    const Eigen::Matrix3d K = skew3(phi_rad);
    return Eigen::Matrix3d::Identity() + (1.0 - a2 / 6.0) * K + (0.5 - a2 / 24.0) * K * K;
  }
  const double angle = std::sqrt(a2);
  return rotation_about(phi_rad / angle, angle);
}

namespace {

/// The coefficients of the right Jacobian of SO(3), J_r(φ) = I - c1 [φ×] + c2 [φ×]², for
/// which exp([φ×])^T d/dt exp([φ×]) = [(J_r(φ) φ̇)×]: c1 = (1 - cos a)/a², c2 = (a - sin a)/a³.
struct RightJacobian {
  double c1 = 0.5, c2 = 1.0 / 6.0;
  Eigen::Matrix3d J = Eigen::Matrix3d::Identity();
};

RightJacobian right_jacobian(const Eigen::Vector3d& phi) {
  RightJacobian r;
  const double a2 = phi.squaredNorm();
  if (a2 < 1e-6) {  // series: the next terms are a⁴/720 and a⁴/5040, < 2e-15
    r.c1 = 0.5 - a2 / 24.0;
    r.c2 = 1.0 / 6.0 - a2 / 120.0;
  } else {
    const double a = std::sqrt(a2);
    r.c1 = (1.0 - std::cos(a)) / a2;
    r.c2 = (a - std::sin(a)) / (a2 * a);
  }
  const Eigen::Matrix3d K = skew3(phi);
  r.J = Eigen::Matrix3d::Identity() - r.c1 * K + r.c2 * K * K;
  return r;
}

void axis_state(const sequences::AxisMotion& m, double tau_s, double& angle, double& rate,
                double& accel) {
  angle = m.angle0_rad + m.rate0_radps * tau_s + 0.5 * m.accel_radps2 * tau_s * tau_s;
  rate = m.rate0_radps + m.accel_radps2 * tau_s;
  accel = m.accel_radps2;
}

}  // namespace

sequences::TableState state_in_segment(const sequences::ProfileSegment& seg, double t_s) {
  sequences::TableState s;
  const double tau_s = t_s - seg.t0_s;
  axis_state(seg.outer, tau_s, s.outer_rad, s.outer_rate_radps, s.outer_accel_radps2);
  axis_state(seg.inner, tau_s, s.inner_rad, s.inner_rate_radps, s.inner_accel_radps2);
  s.at_rest = seg.kind == sequences::SegmentKind::kRest;
  return s;
}

TableKinematics::TableKinematics(const AltTable& table, const AltEffects& fx, double true_lat_rad,
                                 double true_gravity_mps2, double earth_rate_radps)
    : C_bp_(table.C_bp), wobble_rad_(fx.table_wobble_rad) {
  C_left_ = rotation_from_vector(table.misalignment_rad) *
            rotation_about(Eigen::Vector3d::UnitZ(), table.heading_rad);
  a_o_ = table.outer_axis_t.normalized();
  a_i_ = table.inner_axis_o.normalized();
  // Non-orthogonality: the inner axis turned towards the outer one about their common normal.
  const Eigen::Vector3d normal = a_i_.cross(a_o_).normalized();
  a_i_lean_ = rotation_about(normal, fx.table_nonorthogonality_rad) * a_i_;
  u1_ = (a_o_ - a_o_.dot(a_i_) * a_i_).normalized();
  u2_ = a_i_.cross(u1_);
  wobble_ = !wobble_rad_.isZero();
  w_ie_n_ =
      earth_rate_radps * Eigen::Vector3d(std::cos(true_lat_rad), 0.0, -std::sin(true_lat_rad));
  f_n_ = Eigen::Vector3d(0.0, 0.0, -true_gravity_mps2);  // at rest on the table: f = -g
}

Eigen::Vector3d TableKinematics::wobble_o(double inner_rad) const {
  // R(a_i, -inner) w by Rodrigues on the vector (w is perpendicular to a_i).
  const Eigen::Vector3d w = wobble_rad_.x() * u1_ + wobble_rad_.y() * u2_;
  return std::cos(inner_rad) * w - std::sin(inner_rad) * a_i_.cross(w);
}

Eigen::Matrix3d TableKinematics::C_bn(double outer_rad, double inner_rad) const {
  const Eigen::Matrix3d tilt =
      wobble_ ? rotation_from_vector(wobble_o(inner_rad)) : Eigen::Matrix3d::Identity();
  return C_left_ * rotation_about(a_o_, outer_rad) * tilt * rotation_about(a_i_lean_, inner_rad) *
         C_bp_;
}

BodyKinematics TableKinematics::at(const sequences::TableState& s, bool with_wdot) const {
  const Eigen::Matrix3d A_o = rotation_about(a_o_, s.outer_rad);
  const Eigen::Matrix3d A_i = rotation_about(a_i_lean_, s.inner_rad);
  Eigen::Matrix3d T = Eigen::Matrix3d::Identity();
  RightJacobian J;
  Eigen::Vector3d delta = Eigen::Vector3d::Zero(), delta_dot = Eigen::Vector3d::Zero();
  if (wobble_) {
    delta = wobble_o(s.inner_rad);
    T = rotation_from_vector(delta);
    J = right_jacobian(delta);
    delta_dot = -s.inner_rate_radps * a_i_.cross(delta);
  }
  BodyKinematics k;
  k.C_bn = C_left_ * A_o * T * A_i * C_bp_;
  // The gimbal rates, each expressed in the platform frame (header: ω_nb_b).
  const Eigen::Vector3d outer_T = T.transpose() * (s.outer_rate_radps * a_o_);
  const Eigen::Vector3d w_T = J.J * delta_dot;
  const Eigen::Vector3d v_i = A_i.transpose() * (outer_T + w_T);
  const Eigen::Vector3d w_nb_b = C_bp_.transpose() * (v_i + s.inner_rate_radps * a_i_lean_);
  const Eigen::Vector3d w_ie_b = k.C_bn.transpose() * w_ie_n_;
  k.w_ib_b = w_nb_b + w_ie_b;
  k.f_b = k.C_bn.transpose() * f_n_;
  if (with_wdot) {
    // d/dt of each term: d(A^T)/dt = -[θ̇ a×] A^T, d(T^T)/dt = -[ω_T×] T^T, and ω̇_T = J δ̈ +
    // J̇ δ̇ where |δ| is constant (δ turns rigidly), so c1, c2 are and J̇ δ̇ = c2 δ̇ × (δ × δ̇).
    const Eigen::Vector3d delta_ddot =
        -s.inner_accel_radps2 * a_i_.cross(delta) - s.inner_rate_radps * a_i_.cross(delta_dot);
    const Eigen::Vector3d v_dot = -w_T.cross(outer_T) +
                                  T.transpose() * (s.outer_accel_radps2 * a_o_) + J.J * delta_ddot +
                                  J.c2 * delta_dot.cross(delta.cross(delta_dot));
    const Eigen::Vector3d wdot_p = A_i.transpose() * v_dot -
                                   s.inner_rate_radps * a_i_lean_.cross(v_i) +
                                   s.inner_accel_radps2 * a_i_lean_;
    // The Earth-rate term turns with the body: d/dt(C_bn^T ω_ie_n) = -ω_nb_b × (C_bn^T ω_ie_n).
    k.wdot_ib_b = C_bp_.transpose() * wdot_p - w_nb_b.cross(w_ie_b);
  }
  return k;
}

}  // namespace imucal::tools::altsim
