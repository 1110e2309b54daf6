#pragma once
// Effects catalogue slot (DESIGN §7): unmodelled physics the truth simulator can inject and the
// gap diagnosis can hypothesise. Every field defaults to "off" (zero). The full catalogue is its
// own issue; the slot and the first sensor-level effects live here so the simulator, the
// estimators and diagnosis share one definition.
#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "calib/conventions.hpp"

namespace imucal::calib {

struct Effects {
  /// Accelerometer quadratic term: δf_i = K2_i f_i^2, in 1/(m/s^2) (10 µg/g^2 ≈ 1.02e-6).
  Eigen::Vector3d accel_k2_per_mps2 = Eigen::Vector3d::Zero();
  /// Accelerometer asymmetry: δf_i = Kap_i |f_i| (dimensionless).
  Eigen::Vector3d accel_asym = Eigen::Vector3d::Zero();
  /// Gyro g-sensitivity: δw = G f, in (rad/s)/(m/s^2).
  Eigen::Matrix3d gyro_g_sens = Eigen::Matrix3d::Zero();
  /// Size effect: lever arm of accelerometer i from the rotation centre, body frame, m.
  std::array<Eigen::Vector3d, 3> accel_lever_arm_m{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                                   Eigen::Vector3d::Zero()};
  /// Encoder log lags the IMU by this much (table–IMU time offset), s.
  double table_time_offset_s = 0.0;

  bool any() const;
  /// Names of the active effects, for truth.json and reports.
  std::vector<std::string> active_names() const;
};

inline bool Effects::any() const { return !active_names().empty(); }

inline std::vector<std::string> Effects::active_names() const {
  std::vector<std::string> n;
  if (!accel_k2_per_mps2.isZero()) n.push_back("accel_quadratic_k2");
  if (!accel_asym.isZero()) n.push_back("accel_asymmetry");
  if (!gyro_g_sens.isZero()) n.push_back("gyro_g_sensitivity");
  for (const auto& r : accel_lever_arm_m)
    if (!r.isZero()) {
      n.push_back("size_effect");
      break;
    }
  if (table_time_offset_s != 0.0) n.push_back("table_time_offset");
  return n;
}

}  // namespace imucal::calib
