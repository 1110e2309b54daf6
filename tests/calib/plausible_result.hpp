#pragma once
// A plausible calibration result for the tests of what judges results (cross-check, limit
// checks): the default unit's parameters with navigation-grade 1-σ uncertainties, converged.
#include <string>

#include "calib/core/calibration_input.hpp"
#include "calib/core/conventions.hpp"
#include "calib/sim/truth_sim.hpp"

namespace imucal::calib::testing {
using namespace imucal::calib::core;
using namespace imucal::calib::effects;

inline CalibrationResult plausible_result(const std::string& method) {
  CalibrationResult r;
  r.method = method;
  r.params = default_unit().params;
  r.sigma.accel_bias_mps2.setConstant(3.0 * kMicroG_mps2);
  r.sigma.accel_M.setConstant(5e-6);
  r.sigma.gyro_bias_radps.setConstant(0.001 * kDegPerHourToRadPerSec);
  r.sigma.gyro_M.setConstant(4e-6);
  r.sigma.table_misalignment_rad.setConstant(1.0 * kArcsecToRad);
  r.converged = true;
  r.iterations = 4;
  return r;
}

}  // namespace imucal::calib::testing
