#pragma once
// The station's calibration job in one call: both independent methods, each evaluated (paper
// §VII), then the cross-check (DESIGN §6). Used by `imucal calibrate` and, later, by stationd's
// worker, so the two can never drift apart.
#include <functional>
#include <optional>
#include <string>

#include "calib/ains.hpp"
#include "calib/calibration_input.hpp"
#include "calib/crosscheck.hpp"
#include "calib/evaluation.hpp"
#include "calib/nlsq.hpp"

namespace imucal::calib {

enum class MethodSelection { kAins, kNlsq, kAll };

struct PipelineOptions {
  MethodSelection methods = MethodSelection::kAll;
  AinsOptions ains;
  NlsqOptions nlsq;
  EvaluationOptions evaluation;
  CrossCheckOptions crosscheck;
  /// Called with a short phase description ("AINS", "NLSQ", "evaluating AINS", ...) before each
  /// phase, so front ends can show progress. May be empty.
  std::function<void(const std::string&)> on_phase;
};

struct MethodOutcome {
  CalibrationResult result;
  EvaluationMetrics metrics;
};

struct PipelineResult {
  std::optional<MethodOutcome> ains;
  std::optional<MethodOutcome> nlsq;
  std::optional<CrossCheckResult> crosscheck;  ///< only when both methods ran
};

PipelineResult run_calibration(const CalibrationInput& in, const PipelineOptions& opt = {});

}  // namespace imucal::calib
