#pragma once
// Rest detection that needs no calibration (issue #21 item 2). calib/core/rest_detector.hpp
// thresholds the magnitude of the uncorrected rate at 1 °/s: right for a navigation-grade unit,
// blind for a MEMS gyro whose offset alone is a few °/s (it is never "at rest"). This detector
// looks at how the raw signals *vary*, as the static-interval detectors of the multi-position
// literature do, and so works on any offset, scale or misalignment:
//
//  1. per sample, the RMS deviation (per axis, about the window mean) of the rate ω = dθ/dt and of
//     the specific force f = dv/dt over a short centred window (window_s);
//  2. the unit's own noise: the quietest windows of the record (the `noise_quantile` of each
//     statistic — the record must be at least that fraction at rest, a hand-placed run is most of
//     it); a window is quiet when both statistics are below max(√variance_factor × that noise, the
//     grade's still floor) — the floor keeps a very quiet unit on a bench or a calm deck "still";
//     the thresholds are at least the grade's tremor rate and tremor force (issue #48 item 2): a
//     unit held still by hand shakes by 0.3–1 °/s, ten times its bench noise, and its specific
//     force by up to 2.5 times its bench noise, where a turn varies the specific force by tens to
//     hundreds of mg and the rate by tens of °/s, so the accelerometer decides and the gyro is a
//     second opinion;
//  3. quiet spans of at least min_rest_s, less edge_guard_s at both ends, are rest candidates;
//  4. a constant-rate rotation (a turntable's cruise about the vertical) varies neither signal: the
//     unit's common gyro offset is the median of the candidates' mean rates, and a sample whose
//     window's mean rate departs from it by more than the grade's rest_rate_spread, or where a hand
//     may hold the unit the tremor rate (a hand drifts as well as shakes: a short window's mean
//     reaches 1–2 °/s), is turning, not at rest; the spans are then cut again as in step 3. At
//     the tremor grades a turn slower than the tremor rate is therefore rest unless the
//     accelerometer sees it: a constant-rate turn about the vertical is (the price of hand-held
//     rests; a factory table's cruise is 10 °/s or more).
#include <Eigen/Core>
#include <vector>

#include "calib/core/imu_increment.hpp"
#include "calib/core/unit_grade.hpp"

namespace imucal::calib::core {

struct VariationRestOptions {
  double window_s = 0.2;          ///< centred window of the variation statistics
  double noise_quantile = 0.05;   ///< quietest fraction of windows that sets the unit's noise
  double variance_factor = 4.0;   ///< quiet: variance below this × the noise variance (or floor)
  double min_rest_s = 2.0;        ///< shorter quiet spans are not rest (the grade's: min_rest_s)
  double edge_guard_s = 0.05;     ///< trimmed from both ends of every rest span
  double still_rate_radps = 0.0;  ///< the grade's floors (variation_rest_options)
  double still_force_mps2 = 0.0;
  double rest_rate_spread_radps = 0.0;  ///< > 0: see step 4
  double tremor_rate_radps = 0.0;  ///< the gyro's threshold (step 2) and spread (step 4) at least
  double tremor_force_noise_ratio = 0.0;  ///< the accelerometer's threshold, × its noise, at least
};

/// The defaults with the grade's floors, rest-rate spread, tremor allowances and shortest rest
/// (calib/core/unit_grade.hpp).
VariationRestOptions variation_rest_options(Grade grade);

struct VariationRestResult {
  std::vector<bool> at_rest;      ///< per sample
  int rests = 0;                  ///< rest spans kept
  int rotations_rejected = 0;     ///< quiet spans rejected as constant-rate rotations (step 4)
  double rate_noise_radps = 0.0;  ///< the unit's rate noise per sample, RMS per axis (step 2)
  double force_noise_mps2 = 0.0;
  Eigen::Vector3d gyro_offset_radps = Eigen::Vector3d::Zero();  ///< step 4 (zero: no rest)
};

/// Throws std::invalid_argument naming the option that is out of range, or the first sample with
/// a non-finite increment or a non-positive dt_s.
VariationRestResult detect_rest_by_variation(const ImuSeries& imu,
                                             const VariationRestOptions& options);

}  // namespace imucal::calib::core
