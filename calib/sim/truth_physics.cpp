#include "calib/sim/truth_physics.hpp"

#include <cmath>

#include "calib/core/rotation.hpp"
#include "calib/effects/sensor_effects.hpp"
#include "calib/effects/site_errors.hpp"
#include "calib/effects/table_imperfections.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

TruthKinematics::TruthKinematics(const TableGeometry& geometry, const Site& site,
                                 const UnitModel& unit, double dt_s)
    : table_(geometry),
      geometry_(geometry),
      nonorth_rad_(unit.effects.table_nonorthogonality_rad),
      wobble_rad_(unit.effects.table_wobble_rad),
      misalignment_rad_(unit.params.table_misalignment_rad),
      lever_arm_m_(unit.effects.accel_lever_arm_m) {
  // The physics happens at the true site; the station's configured one may be off (ARCHITECTURE
  // §7).
  const EarthModel earth(
      true_site(site, unit.effects.gravity_error_mps2, unit.effects.latitude_error_rad));
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
  const Eigen::Matrix3d table =
      nonorth_rad_ == 0.0 && wobble_rad_.isZero()
          ? table_.C_bn(s.outer_rad, s.inner_rad)
          : table_C_bn<double>(geometry_, s.outer_rad, s.inner_rad, nonorth_rad_, wobble_rad_);
  return rotvec_to_matrix<double>(misalignment_rad_) * table;
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
  return C * size_effect_f_b<double>(lever_arm_m_, w_ib_b, wdot_b);
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
      acc +=
          GaussLegendre3::kWeight[q] * h *
          (rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n_ * (t - t0))) * lever_f_n(state_at(t)));
    }
  }
  return C_bn_prev.transpose() * acc;
}

Eigen::Vector3d TruthKinematics::dv_hand(
    const Eigen::Matrix3d& C_bn_prev, double t0, double t1,
    const std::function<HandState(double t_s)>& hand_at) const {
  const double h = t1 - t0;
  Eigen::Vector3d acc = Eigen::Vector3d::Zero();
  for (int q = 0; q < 3; ++q) {
    const double t = t0 + GaussLegendre3::kNode[q] * h;
    const HandState s = hand_at(t);
    const Eigen::Vector3d a_n = s.C_bn * s.f_b + 2.0 * w_ie_n_.cross(s.v_n);
    acc += GaussLegendre3::kWeight[q] * h *
           (rotvec_to_matrix<double>(Eigen::Vector3d(w_ie_n_ * (t - t0))) * a_n);
  }
  return C_bn_prev.transpose() * acc;
}

TruthSensor::TruthSensor(const UnitModel& unit, double dt_s, uint64_t seed, bool noise)
    : fx_(unit.effects),
      err_(ImuErrorModel<double>::from_params(unit.params)),
      dt_s_(dt_s),
      noise_(noise),
      rng_(seed),
      // The output_filter effect acts on the signal whether or not noise is drawn: it is a lag.
      f_dth_{unit.effects.output_filter_gyro},
      f_dv_{unit.effects.output_filter_accel},
      // The quantisation effect: the unit's real LSBs replace the declared ones.
      q_dth_{noise ? (unit.effects.quant_dtheta_rad > 0.0 ? unit.effects.quant_dtheta_rad
                                                          : unit.noise.dtheta_lsb_rad)
                   : 0.0},
      q_dv_{noise ? (unit.effects.quant_dv_mps > 0.0 ? unit.effects.quant_dv_mps
                                                     : unit.noise.dv_lsb_mps)
                  : 0.0},
      sd_dth_(unit.noise.arw_rad_per_sqrt_s * std::sqrt(dt_s)),
      sd_dv_(unit.noise.vrw_mps_per_sqrt_s * std::sqrt(dt_s)) {
  if (noise_) {
    gm_g_.init(unit.noise.gyro_bias_instability_radps, unit.noise.gyro_bias_tau_s, dt_s, rng_);
    gm_a_.init(unit.noise.accel_bias_instability_mps2, unit.noise.accel_bias_tau_s, dt_s, rng_);
    // The bias_instability effect: a second, undeclared Gauss-Markov process (draws nothing when
    // off, so effect-free runs keep their noise stream).
    fx_gm_g_.init(unit.effects.instability_gyro_radps, unit.effects.instability_tau_s, dt_s, rng_);
    fx_gm_a_.init(unit.effects.instability_accel_mps2, unit.effects.instability_tau_s, dt_s, rng_);
  }
}

void TruthSensor::reseed_noise(uint64_t seed) {
  rng_.seed(seed);
  normal_.reset();  // drops the polar method's cached second value, drawn from the old stream
}

void TruthSensor::measure(const Eigen::Vector3d& dtheta, const Eigen::Vector3d& dv, double t0_s,
                          ImuIncrement& out) {
  const double dt_s = dt_s_;
  // Sensor-level effects (ARCHITECTURE §7, calib/effects/) at the interval-mean kinematics; the
  // size effect is already in dv (integrated exactly by TruthKinematics::dv_lever).
  SensorKinematics kin;
  kin.f_b = dv / dt_s;
  kin.w_b = dtheta / dt_s;
  kin.t0_s = t0_s;
  kin.dt_s = dt_s;
  const IncrementDelta fx = sensor_effects_delta(fx_, kin, /*include_size_effect=*/false);

  Eigen::Vector3d dth_meas = err_.corrupt_dtheta(dtheta, dt_s) + fx.dtheta;
  Eigen::Vector3d dv_meas = err_.corrupt_dv(dv, dt_s) + fx.dv;
  if (noise_) {
    gm_g_.step(rng_);
    gm_a_.step(rng_);
    fx_gm_g_.step(rng_);
    fx_gm_a_.step(rng_);
    for (int i = 0; i < 3; ++i) {
      dth_meas(i) += sd_dth_ * normal_(rng_) + (gm_g_.x(i) + fx_gm_g_.x(i)) * dt_s;
      dv_meas(i) += sd_dv_ * normal_(rng_) + (gm_a_.x(i) + fx_gm_a_.x(i)) * dt_s;
    }
  }
  // The sensor's output filter smooths the noisy increments; the register then rounds its output.
  out.dtheta_rad = q_dth_.apply(f_dth_.apply(dth_meas));
  out.dv_mps = q_dv_.apply(f_dv_.apply(dv_meas));
}

}  // namespace imucal::calib::sim
