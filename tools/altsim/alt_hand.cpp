#include "tools/altsim/alt_hand.hpp"

#include <algorithm>
#include <cmath>

#include "tools/altsim/alt_random.hpp"

namespace imucal::tools::altsim {

namespace {

constexpr double kFade_s = 0.25;

/// The unit quaternion (w, v) of the rotation vector θ and its time derivative for θ̇.
void quaternion_of(const Eigen::Vector3d& th, const Eigen::Vector3d& thdot, double& q0,
                   Eigen::Vector3d& qv, double& dq0, Eigen::Vector3d& dqv) {
  const double a = th.norm();
  if (a < 1e-12) {  // q = (1, θ/2) to first order, q̇ = (0, θ̇/2)
    q0 = 1.0;
    qv = 0.5 * th;
    dq0 = -0.25 * th.dot(thdot);
    dqv = 0.5 * thdot;
    return;
  }
  const Eigen::Vector3d u = th / a;
  const double adot = u.dot(thdot);
  const Eigen::Vector3d udot = (thdot - u * adot) / a;
  const double c = std::cos(0.5 * a), s = std::sin(0.5 * a);
  q0 = c;
  qv = s * u;
  dq0 = -0.5 * s * adot;
  dqv = 0.5 * c * adot * u + s * udot;
}

}  // namespace

AltHand::AltHand(const sequences::MotionProfile& profile, const AltEffects& fx, uint64_t seed) {
  if (fx.tremor_rate_rms_radps == 0.0 && fx.tremor_tilt_rms_rad == 0.0) return;
  Xoshiro256ss rng(seed ^ 0x68616E64ULL);  // "hand": a stream of its own
  PolarNormal normal(seed ^ 0x7069766FULL);
  for (const auto& seg : profile.segments) {
    if (seg.kind != sequences::SegmentKind::kRest) {
      index_.push_back(-1);
      continue;
    }
    Rest r;
    r.t0_s = seg.t0_s;
    r.t1_s = seg.t1_s;
    for (auto& axis : r.waves)
      for (size_t j = 0; j < axis.size(); ++j) {
        const bool tremor = j < 3;
        const double f_hz = tremor ? 6.0 + 5.0 * rng.uniform01() : 0.3 + 0.9 * rng.uniform01();
        Sinusoid& s = axis[j];
        s.w_radps = 2.0 * kPi * f_hz;
        s.phase_rad = 2.0 * kPi * rng.uniform01();
        // Three tremor sinusoids share the mean-square rate, two sway ones the mean-square angle.
        s.amp_rad = tremor ? fx.tremor_rate_rms_radps * std::sqrt(2.0 / 3.0) / s.w_radps
                           : fx.tremor_tilt_rms_rad;
      }
    const Eigen::Vector3d dir(normal(), normal(), normal());
    r.rho_b_m = fx.tremor_pivot_m * dir / dir.norm();
    index_.push_back(static_cast<int>(rests_.size()));
    rests_.push_back(r);
  }
}

void AltHand::angle(const Rest& r, double t_s, Eigen::Vector3d& th, Eigen::Vector3d& thdot) const {
  th.setZero();
  thdot.setZero();
  const double tau = t_s - r.t0_s, T = r.t1_s - r.t0_s;
  if (!(tau > 0.0 && tau < T)) return;
  // The fade: sin² of the distance from the nearer end over a quarter second (or a quarter rest).
  const double fade = std::min(kFade_s, 0.25 * T), x = std::min(tau, T - tau);
  double g = 1.0, dg = 0.0;
  if (x < fade) {
    const double a = 0.5 * kPi * x / fade;
    g = std::sin(a) * std::sin(a);
    dg = (tau < T - tau ? 1.0 : -1.0) * 2.0 * std::sin(a) * std::cos(a) * 0.5 * kPi / fade;
  }
  for (int i = 0; i < 3; ++i) {
    double s = 0.0, ds = 0.0;
    for (const Sinusoid& w : r.waves[static_cast<size_t>(i)]) {
      s += w.amp_rad * std::sin(w.w_radps * tau + w.phase_rad);
      ds += w.amp_rad * w.w_radps * std::cos(w.w_radps * tau + w.phase_rad);
    }
    th(i) = g * s;
    thdot(i) = dg * s + g * ds;
  }
}

Eigen::Vector3d AltHand::rate(const Rest& r, double t_s) const {
  Eigen::Vector3d th, thdot;
  angle(r, t_s, th, thdot);
  double q0, dq0;
  Eigen::Vector3d qv, dqv;
  quaternion_of(th, thdot, q0, qv, dq0, dqv);
  // q̇ = ½ q ⊗ (0, ω): ω = 2 vec(q* ⊗ q̇) = 2 (q0 q̇v − q̇0 qv − qv × q̇v).
  return 2.0 * (q0 * dqv - dq0 * qv - qv.cross(dqv));
}

HandPose AltHand::at(size_t segment, double t_s) const {
  HandPose p;
  if (!active() || segment >= index_.size() || index_[segment] < 0) return p;
  const Rest& r = rests_[static_cast<size_t>(index_[segment])];
  Eigen::Vector3d thdot;
  angle(r, t_s, p.theta_rad, thdot);
  p.w_b = rate(r, t_s);
  constexpr double h = 1e-5;  // central differences: ~(ωh)²/6 of ω̇, 1e-7 at 11 Hz
  p.wdot_b = (rate(r, t_s + h) - rate(r, t_s - h)) / (2.0 * h);
  return p;
}

Eigen::Vector3d AltHand::pivot_to_unit_b(size_t segment) const {
  if (!active() || segment >= index_.size() || index_[segment] < 0) return Eigen::Vector3d::Zero();
  return rests_[static_cast<size_t>(index_[segment])].rho_b_m;
}

}  // namespace imucal::tools::altsim
