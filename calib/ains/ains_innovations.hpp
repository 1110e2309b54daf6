#pragma once
// The AINS filter's innovations under a fixed calibration (issue #21 item 4: a sea run's gap
// residuals). A run at sea has no rest that is still — the deck rocks, heaves and drifts — so what
// it observes of the unit's model is what the navigation filter makes of it: each GNSS fix and
// depth update predicted from the compensated increments. With the sensor parameters held at a
// calibration (not estimated: their prior σ is zero) the pass is a navigation-only Kalman filter,
// and under the model its scalar innovations ν/√s are independent N(0, 1) (the innovations of a
// Kalman filter are white). An unmodelled effect of the unit shows as a departure of that
// sequence, and its signature is the change of the innovations it makes (Willsky & Jones' GLR
// test for a failure of known shape, here obtained by differences of this one function).
#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "calib/ains/ains.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::calib::ains {
using namespace calib::core;

struct AinsInnovation {
  enum Kind : int {
    kAttitudeX = 0,  ///< factory: table orientation (eq. 34-35), 3 axes
    kZuptNorth = 3,  ///< land, factory: zero velocity (eq. 36-39), north/east/down
    kDepth = 6,      ///< mean depth (eq. 40-43)
    kGnssNorth = 7,  ///< sea: GNSS position (eq. 44-47)
    kGnssEast = 8,
  };
  size_t sample_index = 0;
  double t_s = 0.0;
  int kind = kDepth;
  double nu = 0.0;  ///< innovation z - h x̂ (m, m/s or rad)
  double s = 0.0;   ///< its predicted variance (same unit squared)
};

struct AinsInnovations {
  Eigen::Matrix3d C_bn0 = Eigen::Matrix3d::Identity();  ///< the attitude the INS started from
  std::vector<AinsInnovation> rows;                     ///< every aiding update, in time order
};

/// One forward pass with the sensor parameters held at `params` (ς included) and every scalar
/// innovation recorded. The INS starts at the first rest from opt.initial_C_bn or, when empty,
/// from the coarse alignment with `params` (field settings), its error estimated with the
/// options' initial σ. Throws as calibrate_ains does for input it cannot use.
AinsInnovations ains_innovations(const CalibrationInput& in, const ParamSet& params,
                                 const AinsOptions& opt = {});

}  // namespace imucal::calib::ains
