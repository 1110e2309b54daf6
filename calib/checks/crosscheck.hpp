#pragma once
// Cross-check of two independent calibrations (ARCHITECTURE §6): every parameter must agree within
// k·sqrt(σ_A² + σ_B²) and both methods' evaluation metrics (calib/checks/evaluation.hpp) must be
// under their limits. Anything else sends the run to human REVIEW with the failing terms, stated in
// human units so an operator can read them.
#include <string>
#include <vector>

#include "calib/checks/evaluation.hpp"
#include "calib/core/calibration_input.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

struct CrossCheckOptions {
  double k_sigma = 4.0;                     ///< agreement bound in combined standard deviations
  double max_orientation_rmse_mdeg = 30.0;  ///< eq. 51-52 limit for each method
  double max_accel_rmse_ug = 40.0;          ///< eq. 53-54 limit for each method
};

struct CrossCheckFailure {
  std::string term;    ///< parameter name (param_info(i).name) or metric name
  std::string detail;  ///< e.g. "accel_bias_mps2[1]: |Δ| = 12.3 µg > 4σ bound 8.1 µg"
};

struct CrossCheckResult {
  bool pass = false;
  std::vector<CrossCheckFailure> failures;
  /// Parameters not compared because one result cannot observe them (ς without a table; ...).
  std::vector<std::string> skipped;
  std::string verdict() const { return pass ? "PASS" : "REVIEW"; }
};

/// Results in different body frames (calib/core/body_frame.hpp) are compared in the accel-symmetric
/// one; parameters either result marks unobservable are skipped (listed in `skipped`); metrics
/// with evaluated == false (no reference) are not checked.
/// Throws std::invalid_argument if an option is not positive and finite.
CrossCheckResult cross_check(const CalibrationResult& a, const EvaluationMetrics& ma,
                             const CalibrationResult& b, const EvaluationMetrics& mb,
                             const CrossCheckOptions& options = {});

}  // namespace imucal::calib::checks
