#include "tools/altsim/alt_sim.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include "tools/altsim/alt_hand.hpp"
#include "tools/altsim/alt_kinematics.hpp"
#include "tools/altsim/alt_random.hpp"

namespace imucal::tools::altsim {

namespace {

/// A unit quaternion (scalar w, vector v) for the body's attitude relative to the start of the
/// sample: it maps vectors in b(t) into b(t_{k-1}).
struct Quat {
  double w = 1.0;
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
};

/// q̇ = ½ q ⊗ (0, ω_b): the kinematic equation with the body-frame rate on the right.
Quat quat_rate(const Quat& q, const Eigen::Vector3d& w_b) {
  return {-0.5 * q.v.dot(w_b), 0.5 * (q.w * w_b + q.v.cross(w_b))};
}

Quat quat_axpy(const Quat& q, double h, const Quat& d) { return {q.w + h * d.w, q.v + h * d.v}; }

/// One classical RK4 step of length h with the rate at the step's start, middle and end.
Quat rk4_step(const Quat& q, const Eigen::Vector3d& w0, const Eigen::Vector3d& wm,
              const Eigen::Vector3d& w1, double h) {
  const Quat k1 = quat_rate(q, w0);
  const Quat k2 = quat_rate(quat_axpy(q, 0.5 * h, k1), wm);
  const Quat k3 = quat_rate(quat_axpy(q, 0.5 * h, k2), wm);
  const Quat k4 = quat_rate(quat_axpy(q, h, k3), w1);
  Quat r{q.w + h / 6.0 * (k1.w + 2.0 * k2.w + 2.0 * k3.w + k4.w),
         q.v + h / 6.0 * (k1.v + 2.0 * k2.v + 2.0 * k3.v + k4.v)};
  // RK4 keeps the norm only to O(h^5); renormalising keeps rounding from accumulating.
  const double n = std::sqrt(r.w * r.w + r.v.squaredNorm());
  r.w /= n;
  r.v /= n;
  return r;
}

/// q x q*: the vector x (in b(t)) expressed in b(t_{k-1}).
Eigen::Vector3d quat_rotate(const Quat& q, const Eigen::Vector3d& x) {
  const Eigen::Vector3d t = 2.0 * q.v.cross(x);
  return x + q.w * t + q.v.cross(t);
}

/// Rotation vector of a unit quaternion (angle < π).
Eigen::Vector3d quat_to_rotvec(const Quat& q) {
  const double n = q.v.norm();
  if (n < 1e-10) return (2.0 / q.w) * q.v;  // atan(n/w)/n = 1/w to O(n²) ~ 1e-20
  return (2.0 * std::atan2(n, q.w) / n) * q.v;
}

/// The increments of one sample before the unit's error model: the ideal ones and the sensor
/// effects integrated alongside them.
struct SampleIntegrals {
  Eigen::Vector3d dtheta = Eigen::Vector3d::Zero(), dv = Eigen::Vector3d::Zero();
  Eigen::Vector3d dtheta_fx = Eigen::Vector3d::Zero(), dv_fx = Eigen::Vector3d::Zero();
};

/// Values the quadrature needs at one node.
struct Node {
  double t_s;              ///< time from the run's start
  Eigen::Vector3d w_ib_b;  ///< body rate, rad/s
  Eigen::Vector3d f_s;     ///< specific force each accelerometer senses (lever arm included)
};

/// Integrates one sample: RK4 on the relative quaternion and composite Simpson for dv and the
/// effects, on `substeps` equal steps per piece between the profile's breakpoints.
class SampleIntegrator {
 public:
  SampleIntegrator(const TableKinematics& kin, const AltEffects& fx, const AltHand& hand,
                   int substeps)
      : kin_(kin), fx_(fx), hand_(hand), substeps_(substeps) {
    for (const auto& r : fx.accel_lever_arm_m) lever_ = lever_ || !r.isZero();
    accel_fx_ = !fx.accel_k2_per_mps2.isZero() || !fx.accel_asym.isZero() ||
                fx.gyro_accel_skew_s != 0.0 || !fx.thermal_accel_mps2.isZero();
    gyro_fx_ = !fx.gyro_g_sens.isZero() || !fx.thermal_gyro_radps.isZero();
  }

  /// The sample [t0_s, t0_s + dt_s]; `cursor` is the segment search's position (moves forward).
  SampleIntegrals integrate(const sequences::MotionProfile& profile, size_t& cursor, double t0_s,
                            double dt_s);

 private:
  Node node(const sequences::ProfileSegment& seg, size_t segment, double t_s) const;
  /// The piece [t0 + a, t0 + b] of the current sample (in profile segment `segment`), a and b
  /// relative to its start t0.
  void piece(const sequences::ProfileSegment& seg, size_t segment, double t0_s, double a_s,
             double b_s);
  void accumulate(const Node& n, double weight);

  const TableKinematics& kin_;
  const AltEffects& fx_;
  const AltHand& hand_;
  int substeps_;
  bool lever_ = false, accel_fx_ = false, gyro_fx_ = false;
  Quat q_;                                           ///< C_{b(t)}^{b(t_{k-1})}
  Eigen::Vector3d sum_dv_, sum_dv_fx_, sum_dth_fx_;  ///< Simpson sums of the current piece
  SampleIntegrals out_;
};

Node SampleIntegrator::node(const sequences::ProfileSegment& seg, size_t segment,
                            double t_s) const {
  const BodyKinematics k = kin_.at(state_in_segment(seg, t_s), lever_ || hand_.active());
  Eigen::Vector3d w = k.w_ib_b, wdot = k.wdot_ib_b, f = k.f_b;
  if (hand_.active()) {
    // The hand turns the body by R = exp([θ×]) (C_bn = C_bn_table R): the table's rate and force
    // seen in the turned body, the hand's rate added; the accelerometers turn about the pivot,
    // fixed on the Earth, as a rigid body at the body's rate w.r.t. inertial space.
    const HandPose h = hand_.at(segment, t_s);
    const Eigen::Matrix3d Rt = rotation_from_vector(h.theta_rad).transpose();
    const Eigen::Vector3d w_table = Rt * k.w_ib_b;
    w = w_table + h.w_b;
    wdot = Rt * k.wdot_ib_b - h.w_b.cross(w_table) + h.wdot_b;
    const Eigen::Vector3d rho = hand_.pivot_to_unit_b(segment);
    f = Rt * k.f_b + wdot.cross(rho) + w.cross(w.cross(rho));
  }
  Node n{t_s, w, f};
  if (lever_)
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d& r = fx_.accel_lever_arm_m[static_cast<size_t>(i)];
      n.f_s(i) += (wdot.cross(r) + w.cross(w.cross(r)))(i);
    }
  return n;
}

void SampleIntegrator::accumulate(const Node& n, double weight) {
  // The specific force in b(t_{k-1}): the dv convention's integrand.
  const Eigen::Vector3d f0 = quat_rotate(q_, n.f_s);
  sum_dv_ += weight * f0;
  if (!accel_fx_ && !gyro_fx_) return;
  // The effects act as the project's error model does: on the compensated increments, "exactly
  // as on rates" (a bias adds b dt, unrotated). So each is evaluated on the node's force and rate
  // expressed in b(t_{k-1}) and integrated as it is — at every node, where the truth simulator
  // takes the interval's mean.
  const double warm = std::exp(-n.t_s / fx_.thermal_tau_s);
  if (accel_fx_) {
    const Eigen::Vector3d w0 = quat_rotate(q_, n.w_ib_b);
    sum_dv_fx_ += weight * (fx_.accel_k2_per_mps2.cwiseProduct(f0.cwiseProduct(f0)) +
                            fx_.accel_asym.cwiseProduct(f0.cwiseAbs()) +
                            fx_.gyro_accel_skew_s * w0.cross(f0) + fx_.thermal_accel_mps2 * warm);
  }
  if (gyro_fx_) sum_dth_fx_ += weight * (fx_.gyro_g_sens * f0 + fx_.thermal_gyro_radps * warm);
}

void SampleIntegrator::piece(const sequences::ProfileSegment& seg, size_t segment, double t0_s,
                             double a_s, double b_s) {
  const double h = (b_s - a_s) / substeps_;
  sum_dv_.setZero();
  sum_dv_fx_.setZero();
  sum_dth_fx_.setZero();
  Node n0 = node(seg, segment, t0_s + a_s);
  accumulate(n0, 1.0);
  for (int j = 1; j <= substeps_; ++j) {
    const Node nm = node(seg, segment, t0_s + (a_s + (j - 0.5) * h));
    const Node n1 = node(seg, segment, t0_s + (a_s + j * h));
    q_ = rk4_step(q_, n0.w_ib_b, nm.w_ib_b, n1.w_ib_b, h);
    // Composite Simpson weights 1, 4, 2, 4, ..., 4, 1 (substeps_ is even).
    accumulate(n1, j == substeps_ ? 1.0 : (j % 2 ? 4.0 : 2.0));
    n0 = n1;
  }
  out_.dv += (h / 3.0) * sum_dv_;
  out_.dv_fx += (h / 3.0) * sum_dv_fx_;
  out_.dtheta_fx += (h / 3.0) * sum_dth_fx_;
}

SampleIntegrals SampleIntegrator::integrate(const sequences::MotionProfile& profile, size_t& cursor,
                                            double t0_s, double dt_s) {
  q_ = Quat{};
  out_ = SampleIntegrals{};
  const auto& segs = profile.segments;
  while (cursor + 1 < segs.size() && segs[cursor].t1_s <= t0_s) ++cursor;
  // One piece per segment the sample overlaps: the angular acceleration jumps at a breakpoint,
  // and neither RK4 nor Simpson may straddle a jump without losing their order. The pieces are
  // laid out from the sample's start so that they add up to dt_s exactly (t1 - t0 in absolute
  // time carries a rounding of ~t * 1e-16: 5e-12 of dt, and of dv, at t = 500 s).
  double a = 0.0;
  for (size_t c = cursor;; ++c) {
    const bool last = c + 1 >= segs.size() || segs[c].t1_s - t0_s >= dt_s;
    const double b = last ? dt_s : segs[c].t1_s - t0_s;
    if (b > a) piece(segs[c], c, t0_s, a, b);
    if (last) break;
    a = b;
  }
  out_.dtheta = quat_to_rotvec(q_);
  return out_;
}

/// Rounds to the LSB and carries the remainder into the next sample, as an accumulating output
/// register does (the rounding never accumulates into a drift).
struct Quantiser {
  double lsb = 0.0;
  Eigen::Vector3d carry = Eigen::Vector3d::Zero();
  Eigen::Vector3d operator()(const Eigen::Vector3d& x) {
    if (lsb <= 0.0) return x;
    const Eigen::Vector3d total = x + carry;
    const Eigen::Vector3d q = (total / lsb).array().round().matrix() * lsb;
    carry = total - q;
    return q;
  }
};

/// The output filter: each output moves (1 - a) of the way from the last output towards the new
/// input (an exponential smoother, started at the first input).
struct Smoother {
  double a = 0.0;
  Eigen::Vector3d last = Eigen::Vector3d::Zero();
  bool started = false;
  Eigen::Vector3d operator()(const Eigen::Vector3d& x) {
    if (a <= 0.0) return x;
    last = started ? Eigen::Vector3d(last + (1.0 - a) * (x - last)) : x;
    started = true;
    return last;
  }
};

/// The unit's stochastic output stage: white noise, the declared and the undeclared Gauss-Markov
/// biases, the output filter (a lag: also without noise), quantisation.
class NoiseStage {
 public:
  NoiseStage(const AltUnit& u, double dt_s, uint64_t seed, bool on)
      : on_(on),
        dt_s_(dt_s),
        normal_(seed),
        sd_dth_(u.noise.arw_rad_per_sqrt_s * std::sqrt(dt_s)),
        sd_dv_(u.noise.vrw_mps_per_sqrt_s * std::sqrt(dt_s)),
        q_dth_{on ? (u.effects.quant_dtheta_rad > 0.0 ? u.effects.quant_dtheta_rad
                                                      : u.noise.dtheta_lsb_rad)
                  : 0.0},
        q_dv_{on ? (u.effects.quant_dv_mps > 0.0 ? u.effects.quant_dv_mps : u.noise.dv_lsb_mps)
                 : 0.0},
        f_dth_{u.effects.output_filter_gyro},
        f_dv_{u.effects.output_filter_accel} {
    if (!on_) return;
    const AltNoise& n = u.noise;
    const AltEffects& fx = u.effects;
    gm_g_ = GaussMarkov3(n.gyro_gm_sigma_radps, n.gyro_gm_tau_s, dt_s, normal_);
    gm_a_ = GaussMarkov3(n.accel_gm_sigma_mps2, n.accel_gm_tau_s, dt_s, normal_);
    fx_gm_g_ = GaussMarkov3(fx.instability_gyro_radps, fx.instability_tau_s, dt_s, normal_);
    fx_gm_a_ = GaussMarkov3(fx.instability_accel_mps2, fx.instability_tau_s, dt_s, normal_);
  }

  void apply(Eigen::Vector3d& dth, Eigen::Vector3d& dv) {
    if (!on_) {
      dth = f_dth_(dth);
      dv = f_dv_(dv);
      return;
    }
    for (GaussMarkov3* g : {&gm_g_, &gm_a_, &fx_gm_g_, &fx_gm_a_}) g->step(normal_);
    for (int i = 0; i < 3; ++i) {
      dth(i) += sd_dth_ * normal_() + (gm_g_.x(i) + fx_gm_g_.x(i)) * dt_s_;
      dv(i) += sd_dv_ * normal_() + (gm_a_.x(i) + fx_gm_a_.x(i)) * dt_s_;
    }
    dth = q_dth_(f_dth_(dth));
    dv = q_dv_(f_dv_(dv));
  }

 private:
  bool on_;
  double dt_s_;
  PolarNormal normal_;
  double sd_dth_, sd_dv_;
  Quantiser q_dth_, q_dv_;
  Smoother f_dth_, f_dv_;
  GaussMarkov3 gm_g_, gm_a_, fx_gm_g_, fx_gm_a_;
};

void check_inputs(const sequences::MotionProfile& profile, const AltUnit& u, const AltOptions& o) {
  if (!(o.rate_hz > 0.0) || !std::isfinite(o.rate_hz))
    throw std::invalid_argument("altsim: rate_hz must be > 0");
  if (o.substeps < 8 || o.substeps % 2 != 0)
    throw std::invalid_argument("altsim: substeps must be even and >= 8, got " +
                                std::to_string(o.substeps));
  if (profile.segments.empty()) throw std::invalid_argument("altsim: empty motion profile");
  const AltEffects& fx = u.effects;
  for (double tau :
       {fx.thermal_tau_s, fx.instability_tau_s, u.noise.gyro_gm_tau_s, u.noise.accel_gm_tau_s})
    if (!(tau > 0.0)) throw std::invalid_argument("altsim: time constants must be > 0");
}

/// The encoder log's sample k: angles of t - offset (a late log), rest flag with the guard.
void encoder_sample(const sequences::MotionProfile& profile, const AltEffects& fx, double guard_s,
                    double t0_s, double t1_s, AltSample& out) {
  const sequences::TableState s = profile.at(t1_s - fx.table_time_offset_s);
  out.outer_deg = s.outer_rad * (180.0 / kPi);
  out.inner_deg = s.inner_rad * (180.0 / kPi);
  const auto& seg = profile.segments[profile.segment_index_at(0.5 * (t0_s + t1_s))];
  out.at_rest = seg.kind == sequences::SegmentKind::kRest && t0_s >= seg.t0_s + guard_s &&
                t1_s <= seg.t1_s - guard_s;
}

}  // namespace

std::vector<AltSample> simulate_alt(const sequences::MotionProfile& profile, const AltTable& table,
                                    const AltSite& site, const AltUnit& unit,
                                    const AltOptions& options) {
  check_inputs(profile, unit, options);
  const AltEffects& fx = unit.effects;
  const AltErrorModel& e = unit.errors;
  const double dt_s = 1.0 / options.rate_hz;
  const size_t n = static_cast<size_t>(std::floor(profile.duration_s() * options.rate_hz + 1e-9));
  // The physics happens at the true site; the station's configured one may be off.
  const TableKinematics kin(table, fx, site.lat_rad + fx.latitude_error_rad,
                            site.gravity_mps2 + fx.gravity_error_mps2, site.earth_rate_radps);
  const AltHand hand(profile, fx, options.seed);
  SampleIntegrator integrator(kin, fx, hand, options.substeps);
  NoiseStage noise(unit, dt_s, options.seed, options.noise);
  std::vector<AltSample> out(n);
  size_t cursor = 0;
  for (size_t k = 0; k < n; ++k) {
    const double t0_s = static_cast<double>(k) * dt_s;
    const double t1_s = static_cast<double>(k + 1) * dt_s;
    const SampleIntegrals in = integrator.integrate(profile, cursor, t0_s, dt_s);
    AltSample& s = out[k];
    s.t_s = t1_s;
    s.dt_s = dt_s;
    // The error model acts on the increments (paper eq. 18, 23); the effects come on top.
    s.dtheta_rad = in.dtheta + e.b_g_radps * dt_s + e.M_g * in.dtheta + in.dtheta_fx;
    s.dv_mps = in.dv + e.b_a_mps2 * dt_s + e.M_a * in.dv + in.dv_fx;
    noise.apply(s.dtheta_rad, s.dv_mps);
    encoder_sample(profile, fx, options.rest_guard_s, t0_s, t1_s, s);
  }
  return out;
}

}  // namespace imucal::tools::altsim
