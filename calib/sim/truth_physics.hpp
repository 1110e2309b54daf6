#pragma once
// The physics of the truth simulator, shared by the batch form (truth_sim.hpp: a whole motion
// profile known in advance) and the streaming form (truth_stream.hpp: the table's motion known only
// as it happens). Two halves:
//  * TruthKinematics — the ideal increments over one interval at the true site (gravity and
//  latitude
//    errors of the effects catalogue applied): exact dθ from the endpoint
//    attitudes w.r.t. inertial space, dv from gravity in the rotating n-frame plus (size effect)
//    the lever-arm specific force by Gauss-Legendre quadrature;
//  * TruthSensor — what the unit makes of them: error model (paper eq. 18, 23), sensor-level
//  effects
//    (ARCHITECTURE §7), noise (ARW, VRW, Gauss-Markov eq. 16-17) and quantisation with carried
//    remainder.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <functional>
#include <random>
#include <vector>

#include "calib/core/earth.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/table_model.hpp"
#include "calib/effects/bias_instability.hpp"
#include "calib/effects/output_filter.hpp"
#include "calib/effects/quantisation.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

/// 3-point Gauss-Legendre on [0, 1]: exact for polynomials up to degree 5.
struct GaussLegendre3 {
  static constexpr double kNode[3] = {0.5 - 0.3872983346207417, 0.5, 0.5 + 0.3872983346207417};
  static constexpr double kWeight[3] = {5.0 / 18.0, 8.0 / 18.0, 5.0 / 18.0};
};

/// Table state at an instant (the profile's analytic state, or a PLC's actual state).
using TableStateAt = std::function<sequences::TableState(double t_s)>;

class TruthKinematics {
 public:
  TruthKinematics(const TableGeometry& geometry, const Site& site, const UnitModel& unit,
                  double dt_s);

  /// True body attitude for a table state: C_bn_true = exp([ς x]) C_bn_table (conventions.hpp), the
  /// table with its imperfections (table_nonorthogonality, table_wobble) if the unit has them.
  Eigen::Matrix3d C_bn(const sequences::TableState& s) const;
  /// Exact rotation vector of the attitude change w.r.t. inertial space over one interval:
  /// C_{b(k)}^{b(k-1)} = C_bn(k-1)^T exp([ω_ie_n x] dt) C_bn(k).
  Eigen::Vector3d dtheta(const Eigen::Matrix3d& C_bn_prev, const Eigen::Matrix3d& C_bn_cur) const;
  /// dv of the interval from gravity alone (no lever arms): C_nb(t_{k-1}) D f_n with
  /// D = ∫_0^dt exp([ω_ie_n x] s) ds and f_n = -g_n (gravity includes the centrifugal term).
  Eigen::Vector3d dv_gravity(const Eigen::Matrix3d& C_bn_prev) const;
  /// True if the unit has accelerometer lever arms (size effect): dv then needs dv_lever().
  bool size_effect() const { return size_effect_; }
  /// Size-effect part of dv over [t0, t1]: C_nb(t0) ∫ exp([ω_ie_n x](t - t0)) C_bn(t) f_lever_b(t)
  /// dt, 3-point Gauss-Legendre on each piece between `edges` (t0, the acceleration breakpoints
  /// inside, t1 — ascending). state_at is called at the nodes in ascending time order.
  Eigen::Vector3d dv_lever(const Eigen::Matrix3d& C_bn_prev, const std::vector<double>& edges,
                           const TableStateAt& state_at) const;
  /// A hand holding the unit at an instant (rest_tremor): its attitude, the hand's specific force
  /// on the accelerometers (body axes) and the unit's velocity about the pivot (n axes).
  struct HandState {
    Eigen::Matrix3d C_bn;
    Eigen::Vector3d f_b = Eigen::Vector3d::Zero(), v_n = Eigen::Vector3d::Zero();
  };
  /// The hand's part of dv over [t0, t1]: C_nb(t0) ∫ exp([ω_ie_n ×](t - t0)) (C_bn f_hand_b +
  /// 2 ω_ie_n × v_hand_n) dt, 3-point Gauss-Legendre (the tremor turns by < 0.7 rad of its phase
  /// within a 100 Hz sample: 3e-8 of the term). The centripetal ω_ie × (ω_ie × d) of the hand's
  /// sub-millimetre displacement d (5e-9 m/s²) is left out.
  Eigen::Vector3d dv_hand(const Eigen::Matrix3d& C_bn_prev, double t0, double t1,
                          const std::function<HandState(double t_s)>& hand_at) const;
  const TableModel& table() const { return table_; }

 private:
  Eigen::Vector3d lever_f_n(const sequences::TableState& s) const;

  TableModel table_;
  TableGeometry geometry_;
  double nonorth_rad_ = 0.0;                              ///< table_nonorthogonality effect
  Eigen::Vector2d wobble_rad_ = Eigen::Vector2d::Zero();  ///< table_wobble effect
  Eigen::Vector3d misalignment_rad_;
  std::array<Eigen::Vector3d, 3> lever_arm_m_;
  bool size_effect_ = false;
  Eigen::Vector3d w_ie_n_;
  Eigen::Vector3d f_n_;
  Eigen::Matrix3d E_dt_;  ///< exp([ω_ie_n x] dt)
  Eigen::Matrix3d D_;     ///< ∫_0^dt exp([ω_ie_n x] s) ds
};

class TruthSensor {
 public:
  /// noise = false: error model and effects only (deterministic, no quantisation).
  TruthSensor(const UnitModel& unit, double dt_s, uint64_t seed, bool noise);
  /// The unit's output for ideal increments (dθ, dv) of the interval starting t0_s after the run's
  /// first sample (the thermal warm-up's clock); fills out.dtheta_rad, dv_mps.
  void measure(const Eigen::Vector3d& dtheta, const Eigen::Vector3d& dv, double t0_s,
               ImuIncrement& out);
  /// Continues with the noise stream of `seed` (the Gauss-Markov states and the quantisers' carries
  /// continue: only the white noise's source changes).
  void reseed_noise(uint64_t seed);

 private:
  Effects fx_;
  ImuErrorModel<double> err_;
  double dt_s_;
  bool noise_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  GaussMarkov3 gm_g_, gm_a_;        ///< the noise model's declared bias instability
  GaussMarkov3 fx_gm_g_, fx_gm_a_;  ///< the bias_instability effect (undeclared)
  OutputFilter f_dth_, f_dv_;       ///< the output_filter effect (before the register)
  Quantiser q_dth_, q_dv_;
  double sd_dth_, sd_dv_;
};

}  // namespace imucal::calib::sim
