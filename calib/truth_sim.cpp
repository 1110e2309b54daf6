#include "calib/truth_sim.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "calib/imu_error_model.hpp"
#include "calib/rotation.hpp"

namespace imucal::calib {

namespace {

// 3-point Gauss-Legendre on [0, 1]: exact for polynomials up to degree 5.
constexpr double kGlNode[3] = {0.5 - 0.3872983346207417, 0.5, 0.5 + 0.3872983346207417};
constexpr double kGlWeight[3] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};

/// Rounds each axis to the LSB, carrying the remainder into the next sample (like a real
/// accumulating output register), so quantisation never accumulates into a drift.
struct Quantiser {
  double lsb = 0.0;
  Eigen::Vector3d carry = Eigen::Vector3d::Zero();
  Eigen::Vector3d apply(const Eigen::Vector3d& x) {
    if (lsb <= 0.0) return x;
    const Eigen::Vector3d total = x + carry;
    Eigen::Vector3d q;
    for (int i = 0; i < 3; ++i) q(i) = std::round(total(i) / lsb) * lsb;
    carry = total - q;
    return q;
  }
};

/// First-order Gauss-Markov process per axis (paper eq. 16-17), exact discretisation.
struct GaussMarkov3 {
  double sigma = 0.0, phi = 0.0, drive = 0.0;
  Eigen::Vector3d x = Eigen::Vector3d::Zero();
  void init(double sigma_, double tau_s, double dt_s, std::mt19937_64& rng) {
    sigma = sigma_;
    if (sigma <= 0.0) return;
    phi = std::exp(-dt_s / tau_s);
    drive = sigma * std::sqrt(1.0 - phi * phi);
    std::normal_distribution<double> n(0.0, 1.0);
    for (int i = 0; i < 3; ++i) x(i) = sigma * n(rng);  // x(0) ~ N(0, σ²), eq. 16
  }
  void step(std::mt19937_64& rng) {
    if (sigma <= 0.0) return;
    std::normal_distribution<double> n(0.0, 1.0);
    for (int i = 0; i < 3; ++i) x(i) = phi * x(i) + drive * n(rng);
  }
};

}  // namespace

UnitModel default_unit() {
  // Values inside DESIGN §7's "default unit" sizes; fixed so that runs are reproducible.
  UnitModel u;
  ParamSet& p = u.params;
  p.accel_bias_mps2 = Eigen::Vector3d(50.0, -40.0, 30.0) * kMicroG_mps2;
  p.accel_M << 300e-6, 120e-6, -80e-6,  //
      -150e-6, -200e-6, 60e-6,          //
      90e-6, -110e-6, 450e-6;
  p.gyro_bias_radps = Eigen::Vector3d(0.010, -0.008, 0.012) * kDegPerHourToRadPerSec;
  p.gyro_M << -150e-6, 200e-6, -100e-6,  //
      80e-6, 400e-6, 150e-6,             //
      -120e-6, 90e-6, 250e-6;
  p.table_misalignment_rad = Eigen::Vector3d(10.0, -15.0, 30.0) * kArcsecToRad;
  u.noise = NoiseModel{};
  return u;
}

Eigen::Matrix3d true_C_bn(const sequences::MotionProfile& profile, const TableModel& table,
                          const UnitModel& unit, double t_s) {
  const sequences::TableState s = profile.at(t_s);
  return rotvec_to_matrix<double>(unit.params.table_misalignment_rad) *
         table.C_bn(s.outer_rad, s.inner_rad);
}

SimResult simulate(const sequences::MotionProfile& profile, const TableGeometry& geometry,
                   const Site& site, const UnitModel& unit, const SimOptions& options) {
  const TableModel table(geometry);
  const EarthModel earth(site);
  const double dt_s = 1.0 / options.rate_hz;
  const size_t n = static_cast<size_t>(std::floor(profile.duration_s() * options.rate_hz + 1e-9));
  const Eigen::Vector3d w_ie_n = earth.w_ie_n();
  // Specific force of a body at rest in the rotating n-frame: f_n = -g_n (gravity includes the
  // centrifugal term).
  const Eigen::Vector3d f_n = -earth.g_n();
  // exp([ω_ie_n x] dt): the n-frame's rotation w.r.t. inertial space over one interval.
  const Eigen::Matrix3d E_dt = rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n * dt_s));
  // D = ∫_0^dt exp([ω_ie_n x] s) ds, so that without lever arms dv_k = C_nb(t_{k-1}) D f_n.
  Eigen::Matrix3d D = Eigen::Matrix3d::Zero();
  for (int q = 0; q < 3; ++q)
    D +=
        kGlWeight[q] * dt_s * rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n * kGlNode[q] * dt_s));

  const Effects& fx = unit.effects;
  bool size_effect = false;
  for (const auto& r : fx.accel_lever_arm_m) size_effect = size_effect || !r.isZero();
  const std::vector<double> breaks = profile.breakpoints();

  const ImuErrorModel<double> err = ImuErrorModel<double>::from_params(unit.params);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  GaussMarkov3 gm_g, gm_a;
  if (options.noise) {
    gm_g.init(unit.noise.gyro_bias_instability_radps, unit.noise.gyro_bias_tau_s, dt_s, rng);
    gm_a.init(unit.noise.accel_bias_instability_mps2, unit.noise.accel_bias_tau_s, dt_s, rng);
  }
  Quantiser q_dth{options.noise ? unit.noise.dtheta_lsb_rad : 0.0};
  Quantiser q_dv{options.noise ? unit.noise.dv_lsb_mps : 0.0};
  const double sd_dth = unit.noise.arw_rad_per_sqrt_s * std::sqrt(dt_s);
  const double sd_dv = unit.noise.vrw_mps_per_sqrt_s * std::sqrt(dt_s);

  auto C_at = [&](double t) { return true_C_bn(profile, table, unit, t); };

  // Lever-arm specific force of accelerometer i, resolved in n: component i of
  // ([ω̇ x] + [ω x]^2) r_i for each axis (the size effect), mapped through C_bn(t).
  auto lever_f_n = [&](double t) -> Eigen::Vector3d {
    const sequences::TableState s = profile.at(t);
    const Eigen::Matrix3d C_bn = C_at(t);
    const Eigen::Vector3d w_ib_b = table.w_nb_b(s) + C_bn.transpose() * w_ie_n;
    const Eigen::Vector3d wdot_b = table.wdot_nb_b(s);
    Eigen::Vector3d f_b;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d& r = fx.accel_lever_arm_m[static_cast<size_t>(i)];
      f_b(i) = (wdot_b.cross(r) + w_ib_b.cross(w_ib_b.cross(r)))(i);
    }
    return C_bn * f_b;
  };

  SimResult out;
  out.imu.resize(n);
  out.table.resize(n);
  out.truth = unit.params;
  Eigen::Matrix3d C_prev = C_at(0.0);
  for (size_t k = 0; k < n; ++k) {
    const double t0 = static_cast<double>(k) * dt_s;
    const double t1 = static_cast<double>(k + 1) * dt_s;
    const Eigen::Matrix3d C_cur = C_at(t1);
    // Exact rotation vector of the attitude change w.r.t. inertial space:
    // C_{b(k)}^{b(k-1)} = C_bn(k-1)^T exp([ω_ie_n x] dt) C_bn(k).
    Eigen::Vector3d dtheta = matrix_to_rotvec(C_prev.transpose() * E_dt * C_cur);
    Eigen::Vector3d dv = C_prev.transpose() * (D * f_n);
    if (size_effect) {
      // Integrate piecewise between the profile's breakpoints (ω̇ jumps there).
      std::vector<double> edges{t0};
      auto it = std::upper_bound(breaks.begin(), breaks.end(), t0);
      for (; it != breaks.end() && *it < t1; ++it) edges.push_back(*it);
      edges.push_back(t1);
      Eigen::Vector3d acc = Eigen::Vector3d::Zero();
      for (size_t e = 0; e + 1 < edges.size(); ++e) {
        const double a = edges[e], h = edges[e + 1] - edges[e];
        for (int q = 0; q < 3; ++q) {
          const double t = a + kGlNode[q] * h;
          acc += kGlWeight[q] * h *
                 (rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n * (t - t0))) * lever_f_n(t));
        }
      }
      dv += C_prev.transpose() * acc;
    }

    // Sensor-level effects (DESIGN §7) on the interval-mean specific force.
    const Eigen::Vector3d f_mean_b = dv / dt_s;
    Eigen::Vector3d dv_fx = Eigen::Vector3d::Zero(), dth_fx = Eigen::Vector3d::Zero();
    for (int i = 0; i < 3; ++i) {
      dv_fx(i) += fx.accel_k2_per_mps2(i) * f_mean_b(i) * f_mean_b(i) * dt_s;
      dv_fx(i) += fx.accel_asym(i) * std::abs(f_mean_b(i)) * dt_s;
    }
    dth_fx += fx.gyro_g_sens * f_mean_b * dt_s;

    Eigen::Vector3d dth_meas = err.corrupt_dtheta(dtheta, dt_s) + dth_fx;
    Eigen::Vector3d dv_meas = err.corrupt_dv(dv, dt_s) + dv_fx;
    if (options.noise) {
      gm_g.step(rng);
      gm_a.step(rng);
      for (int i = 0; i < 3; ++i) {
        dth_meas(i) += sd_dth * normal(rng) + gm_g.x(i) * dt_s;
        dv_meas(i) += sd_dv * normal(rng) + gm_a.x(i) * dt_s;
      }
    }
    ImuIncrement& s = out.imu[k];
    s.t_s = t1;
    s.dt_s = dt_s;
    s.dtheta_rad = q_dth.apply(dth_meas);
    s.dv_mps = q_dv.apply(dv_meas);
    s.temp_c = 25.0;

    // Encoder log: the table's own angles, possibly lagging the IMU clock (time-offset effect).
    const double t_enc = t1 - fx.table_time_offset_s;
    const sequences::TableState ts = profile.at(t_enc);
    TableSample& tab = out.table[k];
    tab.t_s = t1;
    tab.outer_rad = ts.outer_rad;
    tab.inner_rad = ts.inner_rad;
    // At rest only if the whole interval lies inside a rest segment, away from its edges.
    const auto& seg = profile.segments[profile.segment_index_at(0.5 * (t0 + t1))];
    tab.at_rest = seg.kind == sequences::SegmentKind::kRest &&
                  t0 >= seg.t0_s + options.rest_guard_s && t1 <= seg.t1_s - options.rest_guard_s;
    C_prev = C_cur;
  }
  return out;
}

}  // namespace imucal::calib
