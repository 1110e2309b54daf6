#pragma once
// At-rest detection from the IMU data alone (issue #9): on land and at sea the unit is turned by
// hand, so there is no table flag saying when it stands still. A sample is "at rest" when the unit
// is not being turned: over a centred window the mean angular rate is below a threshold far above
// Earth rate and a calm platform's rocking (≈0.1 °/s) and far below a hand rotation (≥ 5 °/s), and
// the specific force is steady. Quiet spans shorter than min_rest_s are dropped (a pause in a
// rotation) and every span is trimmed by edge_guard_s at both ends, so the slow start and end of
// a hand rotation is never called rest.
//
// Robust on a slowly moving, wave-rocked platform: rocking and DP drift change the rate by
// < 0.2 °/s and the specific force by < 0.01 m/s² at the periods involved (5–300 s), well inside
// the thresholds; the detector needs no site, no heading and no calibration.
#include <vector>

#include "calib/core/imu_increment.hpp"

namespace imucal::calib::core {

struct RestDetectorOptions {
  double window_s = 1.0;             ///< centred window of the rate and force statistics
  double max_rate_degps = 1.0;       ///< |mean ω| over the window above this: moving
  double max_force_std_mps2 = 0.05;  ///< std of |f| over the window above this: moving (handling)
  double min_rest_s = 10.0;          ///< shorter quiet spans are not rest
  double edge_guard_s = 1.0;         ///< trimmed from both ends of every rest span
};

/// Quiet samples cut into rests: the maximal quiet runs lasting at least min_rest_s, each trimmed
/// by edge_guard_s at both ends (shared by this detector and calib/core/variation_rest_detector).
std::vector<bool> rests_from_quiet(const ImuSeries& imu, const std::vector<bool>& quiet,
                                   double min_rest_s, double edge_guard_s);

/// Throws std::invalid_argument naming the first sample with a non-finite increment or a
/// non-positive dt_s (what every rest detector needs of its input).
void check_rest_detector_input(const ImuSeries& imu);

/// Per sample: the unit is at rest (not being turned). Throws std::invalid_argument for options
/// that are not positive and finite, naming the option.
std::vector<bool> detect_rest(const ImuSeries& imu, const RestDetectorOptions& options = {});

}  // namespace imucal::calib::core
