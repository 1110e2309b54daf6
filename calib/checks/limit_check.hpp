#pragma once
// Limit checks of one method's result, so that no single calibration is stored or reported as
// good when it cannot be: the estimator converged, every estimate and σ is finite, every
// parameter lies inside the unit's datasheet envelope (a unit far outside it is a broken or
// mis-mounted unit, not a calibration), and — where no second method cross-checks it — the
// paper's metrics (§VII) are under their limits. Used by the pipeline for every method it runs.
#include <string>
#include <vector>

#include "calib/checks/evaluation.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

/// The envelope a healthy navigation-grade unit's parameters lie in before calibration, per
/// group, in SI: ARCHITECTURE §7's default unit is 10–100× inside it, the far-from-nominal test
/// unit (db/archive/units/far.toml: 2 mg, 0.1 °/h, 2000 ppm) 2.5× inside. The table misalignment ς
/// is the fixture's mounting error.
struct DatasheetLimits {
  double accel_bias_mps2 = 5000.0 * kMicroG_mps2;         ///< 5 mg
  double accel_scale = 5000e-6;                           ///< 5000 ppm
  double accel_misalignment_rad = 5000e-6;                ///< 5000 µrad
  double gyro_bias_radps = 1.0 * kDegPerHourToRadPerSec;  ///< 1 °/h
  double gyro_scale = 5000e-6;                            ///< 5000 ppm
  double gyro_misalignment_rad = 5000e-6;                 ///< 5000 µrad
  double table_misalignment_rad = 0.5 * kDegToRad;        ///< 0.5° (fixture)
  /// Limit of group g (SI).
  double of(ParamGroup g) const;
};

/// `limits` widened, group by group, to the envelope of an uncalibrated unit of `grade`
/// (calib/core/unit_grade.hpp): a MEMS gyro 24 % off scale is that unit, not a failed
/// calibration. Navigation grade: `limits` unchanged (the station's datasheet).
DatasheetLimits limits_for_grade(const DatasheetLimits& limits, const UnitPrior& prior);

struct LimitCheckOptions {
  DatasheetLimits datasheet;
  double max_orientation_rmse_mdeg = 30.0;  ///< as the cross-check's (crosscheck.hpp)
  double max_accel_rmse_ug = 40.0;
};

/// The evaluation metrics' limits (orientation RMSE, acceleration RMSE; set for a navigation-grade
/// product) for a unit of `grade`: scaled by the grade's class noise over the navigation class's
/// — ARW for the orientation, VRW for the acceleration (calib/core/unit_grade.hpp: ×200 and ×6 for
/// MEMS, ×40 and ×2 for tactical) — so they keep the same margin over what the unit's own noise
/// leaves. Navigation grade: unchanged.
struct MetricLimits {
  double orientation_rmse_mdeg = 30.0, accel_rmse_ug = 40.0;
};
MetricLimits metric_limits_for_grade(const MetricLimits& limits, Grade grade);

struct LimitFailure {
  std::string method;  ///< "ains", "nlsq", "legacy"
  std::string term;    ///< parameter name, "converged", or a metric name
  std::string
      detail;  ///< e.g. "ains: accel_M[0][0] = 20000 ppm outside the datasheet envelope ±5000 ppm"
};

struct LimitCheckResult {
  bool pass = true;
  std::vector<LimitFailure> failures;
};

/// Checks one method's result (and its metrics when check_metrics and they were evaluated),
/// appending to `out`. Unobservable parameters are not checked. Throws std::invalid_argument
/// when a limit is not positive and finite.
void check_limits(const CalibrationResult& r, const EvaluationMetrics& metrics, bool check_metrics,
                  const LimitCheckOptions& options, LimitCheckResult& out);

}  // namespace imucal::calib::checks
