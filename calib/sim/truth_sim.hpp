#pragma once
// Truth simulator: from a motion profile, a table model, the station site and a unit model, the
// IMU increments a real unit would deliver — exact to the physics (ARCHITECTURE §3, issue #2):
//  * attitude w.r.t. inertial space is analytic: C_bi(t) = C_ni(0) exp([ω_ie_n t x]) C_bn(t), so
//    dθ_k = log(C_bi(t_{k-1})^T C_bi(t_k)) exactly (no sampling of rates);
//  * dv_k = C_bi(t_{k-1})^T ∫ C_bi(t) f_b(t) dt by Gauss-Legendre quadrature split at the profile's
//    breakpoints (the integrand is smooth between them);
//  * then the error model (eq. 18, 23), effects, noise (ARW, VRW, Gauss-Markov), quantisation;
//  * rest_tremor (calib/effects/rest_tremor.hpp) is motion, not a sensor error: a hand turns the
//    unit in each rest segment, C_bn = C_bn_table exp([θ×]), and carries it about its pivot (the
//    hand's specific force integrated with dv); it acts without noise too.
#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "calib/core/earth.hpp"
#include "calib/core/imu_increment.hpp"
#include "calib/core/noise_model.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/table_model.hpp"
#include "calib/core/unit_grade.hpp"
#include "calib/effects/catalogue.hpp"
#include "calib/effects/unit_model.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

struct SimOptions {
  double rate_hz = 100.0;
  uint64_t seed = 1;
  bool noise = true;  ///< false: deterministic increments (for exactness tests)
  double rest_guard_s = kTableRestGuard_s;  ///< at_rest only this far inside rest segments
};

struct SimResult {
  ImuSeries imu;
  std::vector<TableSample> table;  ///< encoder log on the IMU time axis
  ParamSet truth;                  ///< parameters the estimators should recover
};

SimResult simulate(const sequences::MotionProfile& profile, const TableGeometry& geometry,
                   const Site& site, const UnitModel& unit, const SimOptions& options);

/// True body attitude (with ς and any table-geometry effects) at time t — exposed for tests. A
/// hand's motion in the rests (rest_tremor) is not in it: it is drawn per run inside simulate().
Eigen::Matrix3d true_C_bn(const sequences::MotionProfile& profile, const TableModel& table,
                          const UnitModel& unit, double t_s);

}  // namespace imucal::calib::sim
