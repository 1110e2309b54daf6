#include "calib/sim/truth_sim.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "calib/core/rotation.hpp"
#include "calib/effects/rest_tremor.hpp"
#include "calib/effects/table_imperfections.hpp"
#include "calib/effects/table_time_offset.hpp"
#include "calib/sim/truth_physics.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

Eigen::Matrix3d true_C_bn(const sequences::MotionProfile& profile, const TableModel& table,
                          const UnitModel& unit, double t_s) {
  const sequences::TableState s = profile.at(t_s);
  const Effects& fx = unit.effects;
  const Eigen::Matrix3d C =
      fx.table_nonorthogonality_rad == 0.0 && fx.table_wobble_rad.isZero()
          ? table.C_bn(s.outer_rad, s.inner_rad)
          : table_C_bn<double>(table.geometry(), s.outer_rad, s.inner_rad,
                               fx.table_nonorthogonality_rad, fx.table_wobble_rad);
  return rotvec_to_matrix<double>(unit.params.table_misalignment_rad) * C;
}

namespace {

/// The rest_tremor effect on a table run (calib/effects/rest_tremor.hpp): a hand holds the unit in
/// each rest segment of the profile and turns it about a pivot.
class TableHand {
 public:
  TableHand(const sequences::MotionProfile& p, const UnitModel& unit, uint64_t seed)
      : profile_(p), lever_m_(unit.effects.accel_lever_arm_m) {
    const Effects& fx = unit.effects;
    active_ = fx.active(EffectId::kRestTremor);
    if (!active_) return;
    std::vector<double> durations;
    for (const auto& seg : p.segments)
      durations.push_back(seg.kind == sequences::SegmentKind::kRest ? seg.t1_s - seg.t0_s : 0.0);
    motions_ = draw_rest_tremor(fx.tremor_rate_rms_radps, fx.tremor_tilt_rms_rad, fx.tremor_pivot_m,
                                durations, seed);
  }
  bool active() const { return active_; }
  /// The hand's rotation at t, right of the table's attitude (identity outside the rests).
  Eigen::Matrix3d C(double t) const {
    const size_t i = profile_.segment_index_at(t);
    return rotvec_to_matrix<double>(motions_[i].angle_rad(t - profile_.segments[i].t0_s));
  }
  /// The hand at t on a table whose attitude there is C_table.
  TruthKinematics::HandState state(double t, const Eigen::Matrix3d& C_table) const {
    const size_t i = profile_.segment_index_at(t);
    const RestTremorMotion& m = motions_[i];
    const double tau = t - profile_.segments[i].t0_s;
    TruthKinematics::HandState s;
    s.C_bn = C_table * rotvec_to_matrix<double>(m.angle_rad(tau));
    s.f_b = m.specific_force_b_mps2(tau, lever_m_);
    s.v_n = s.C_bn * m.rate_b_radps(tau).cross(m.pivot_to_unit_b_m());
    return s;
  }

 private:
  const sequences::MotionProfile& profile_;
  std::array<Eigen::Vector3d, 3> lever_m_;
  bool active_ = false;
  std::vector<RestTremorMotion> motions_;
};

}  // namespace

SimResult simulate(const sequences::MotionProfile& profile, const TableGeometry& geometry,
                   const Site& site, const UnitModel& unit, const SimOptions& options) {
  const double dt_s = 1.0 / options.rate_hz;
  const size_t n = static_cast<size_t>(std::floor(profile.duration_s() * options.rate_hz + 1e-9));
  const TruthKinematics kin(geometry, site, unit, dt_s);
  TruthSensor sensor(unit, dt_s, options.seed, options.noise);
  const Effects& fx = unit.effects;
  const std::vector<double> breaks = profile.breakpoints();
  const TableStateAt state_at = [&](double t) { return profile.at(t); };

  SimResult out;
  out.imu.resize(n);
  out.table.resize(n);
  out.truth = unit.params;
  const TableHand hand(profile, unit, options.seed);
  auto C_bn_at = [&](double t) {
    const Eigen::Matrix3d C = kin.C_bn(profile.at(t));
    return hand.active() ? Eigen::Matrix3d(C * hand.C(t)) : C;
  };
  Eigen::Matrix3d C_prev = C_bn_at(0.0);
  for (size_t k = 0; k < n; ++k) {
    const double t0 = static_cast<double>(k) * dt_s;
    const double t1 = static_cast<double>(k + 1) * dt_s;
    const Eigen::Matrix3d C_cur = C_bn_at(t1);
    const Eigen::Vector3d dtheta = kin.dtheta(C_prev, C_cur);
    Eigen::Vector3d dv = kin.dv_gravity(C_prev);
    if (hand.active())
      dv += kin.dv_hand(C_prev, t0, t1,
                        [&](double t) { return hand.state(t, kin.C_bn(profile.at(t))); });
    if (kin.size_effect()) {
      std::vector<double> edges{t0};
      auto it = std::upper_bound(breaks.begin(), breaks.end(), t0);
      for (; it != breaks.end() && *it < t1; ++it) edges.push_back(*it);
      edges.push_back(t1);
      dv += kin.dv_lever(C_prev, edges, state_at);
    }
    ImuIncrement& s = out.imu[k];
    s.t_s = t1;
    s.dt_s = dt_s;
    sensor.measure(dtheta, dv, t0, s);
    s.temp_c = 25.0;

    // Encoder log: the table's own angles, possibly lagging the IMU clock (time-offset effect).
    const double t_enc = encoder_source_time_s(t1, fx.table_time_offset_s);
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

}  // namespace imucal::calib::sim
