#include "calib/effects/unit_model.hpp"

#include <Eigen/Core>

#include "calib/core/conventions.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

UnitModel default_unit() {
  // Values inside ARCHITECTURE §7's "default unit" sizes; fixed so that runs are reproducible.
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

}  // namespace imucal::calib::effects
