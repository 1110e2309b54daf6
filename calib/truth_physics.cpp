#include "calib/truth_physics.hpp"

#include <cmath>

#include "calib/rotation.hpp"

namespace imucal::calib {

TruthKinematics::TruthKinematics(const TableGeometry& geometry, const Site& site, const UnitModel& unit,
                                 double dt_s)
    : table_(geometry),
      misalignment_rad_(unit.params.table_misalignment_rad),
      lever_arm_m_(unit.effects.accel_lever_arm_m) {
  const EarthModel earth(site);
  w_ie_n_ = earth.w_ie_n();
  f_n_ = -earth.g_n();
  E_dt_ = rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n_ * dt_s));
  D_.setZero();
  for (int q = 0; q < 3; ++q)
    D_ += GaussLegendre3::kWeight[q] * dt_s *
          rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n_ * GaussLegendre3::kNode[q] * dt_s));
  for (const auto& r : lever_arm_m_) size_effect_ = size_effect_ || !r.isZero();
}

Eigen::Matrix3d TruthKinematics::C_bn(const sequences::TableState& s) const {
  return rotvec_to_matrix<double>(misalignment_rad_) * table_.C_bn(s.outer_rad, s.inner_rad);
}

Eigen::Vector3d TruthKinematics::dtheta(const Eigen::Matrix3d& C_bn_prev,
                                        const Eigen::Matrix3d& C_bn_cur) const {
  return matrix_to_rotvec(C_bn_prev.transpose() * E_dt_ * C_bn_cur);
}

Eigen::Vector3d TruthKinematics::dv_gravity(const Eigen::Matrix3d& C_bn_prev) const {
  return C_bn_prev.transpose() * (D_ * f_n_);
}

// Lever-arm specific force of accelerometer i, resolved in n: component i of
// ([ω̇ x] + [ω x]^2) r_i for each axis (the size effect), mapped through C_bn(t).
Eigen::Vector3d TruthKinematics::lever_f_n(const sequences::TableState& s) const {
  const Eigen::Matrix3d C = C_bn(s);
  const Eigen::Vector3d w_ib_b = table_.w_nb_b(s) + C.transpose() * w_ie_n_;
  const Eigen::Vector3d wdot_b = table_.wdot_nb_b(s);
  Eigen::Vector3d f_b;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d& r = lever_arm_m_[static_cast<size_t>(i)];
    f_b(i) = (wdot_b.cross(r) + w_ib_b.cross(w_ib_b.cross(r)))(i);
  }
  return C * f_b;
}

Eigen::Vector3d TruthKinematics::dv_lever(const Eigen::Matrix3d& C_bn_prev,
                                          const std::vector<double>& edges,
                                          const TableStateAt& state_at) const {
  // Integrate piecewise between the breakpoints (ω̇ jumps there; smooth in between).
  const double t0 = edges.front();
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  for (size_t e = 0; e + 1 < edges.size(); ++e) {
    const double a = edges[e], h = edges[e + 1] - edges[e];
    for (int q = 0; q < 3; ++q) {
      const double t = a + GaussLegendre3::kNode[q] * h;
      acc += GaussLegendre3::kWeight[q] * h *
             (rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n_ * (t - t0))) * lever_f_n(state_at(t)));
    }
  }
  return C_bn_prev.transpose() * acc;
}

Eigen::Vector3d TruthSensor::Quantiser::apply(const Eigen::Vector3d& x) {
  if (lsb <= 0.0) return x;
  const Eigen::Vector3d total = x + carry;
  Eigen::Vector3d q;
  for (int i = 0; i < 3; ++i) q(i) = std::round(total(i) / lsb) * lsb;
  carry = total - q;
  return q;
}

void TruthSensor::GaussMarkov3::init(double sigma_, double tau_s, double dt_s, std::mt19937_64& rng) {
  sigma = sigma_;
  if (sigma <= 0.0) return;
  phi = std::exp(-dt_s / tau_s);
  drive = sigma * std::sqrt(1.0 - phi * phi);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int i = 0; i < 3; ++i) x(i) = sigma * n(rng);  // x(0) ~ N(0, σ²), eq. 16
}

void TruthSensor::GaussMarkov3::step(std::mt19937_64& rng) {
  if (sigma <= 0.0) return;
  std::normal_distribution<double> n(0.0, 1.0);
  for (int i = 0; i < 3; ++i) x(i) = phi * x(i) + drive * n(rng);
}

TruthSensor::TruthSensor(const UnitModel& unit, double dt_s, uint64_t seed, bool noise)
    : fx_(unit.effects),
      err_(ImuErrorModel<double>::from_params(unit.params)),
      dt_s_(dt_s),
      noise_(noise),
      rng_(seed),
      q_dth_{noise ? unit.noise.dtheta_lsb_rad : 0.0},
      q_dv_{noise ? unit.noise.dv_lsb_mps : 0.0},
      sd_dth_(unit.noise.arw_rad_per_sqrt_s * std::sqrt(dt_s)),
      sd_dv_(unit.noise.vrw_mps_per_sqrt_s * std::sqrt(dt_s)) {
  if (noise_) {
    gm_g_.init(unit.noise.gyro_bias_instability_radps, unit.noise.gyro_bias_tau_s, dt_s, rng_);
    gm_a_.init(unit.noise.accel_bias_instability_mps2, unit.noise.accel_bias_tau_s, dt_s, rng_);
  }
}

void TruthSensor::measure(const Eigen::Vector3d& dtheta, const Eigen::Vector3d& dv, ImuIncrement& out) {
  const double dt_s = dt_s_;
  // Sensor-level effects (DESIGN §7) on the interval-mean specific force.
  const Eigen::Vector3d f_mean_b = dv / dt_s;
  Eigen::Vector3d dv_fx = Eigen::Vector3d::Zero(), dth_fx = Eigen::Vector3d::Zero();
  for (int i = 0; i < 3; ++i) {
    dv_fx(i) += fx_.accel_k2_per_mps2(i) * f_mean_b(i) * f_mean_b(i) * dt_s;
    dv_fx(i) += fx_.accel_asym(i) * std::abs(f_mean_b(i)) * dt_s;
  }
  dth_fx += fx_.gyro_g_sens * f_mean_b * dt_s;

  Eigen::Vector3d dth_meas = err_.corrupt_dtheta(dtheta, dt_s) + dth_fx;
  Eigen::Vector3d dv_meas = err_.corrupt_dv(dv, dt_s) + dv_fx;
  if (noise_) {
    gm_g_.step(rng_);
    gm_a_.step(rng_);
    for (int i = 0; i < 3; ++i) {
      dth_meas(i) += sd_dth_ * normal_(rng_) + gm_g_.x(i) * dt_s;
      dv_meas(i) += sd_dv_ * normal_(rng_) + gm_a_.x(i) * dt_s;
    }
  }
  out.dtheta_rad = q_dth_.apply(dth_meas);
  out.dv_mps = q_dv_.apply(dv_meas);
}

}  // namespace imucal::calib
