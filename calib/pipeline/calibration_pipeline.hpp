#pragma once
// The station's calibration job in one call: two independent methods, each evaluated (paper
// §VII), then the cross-check (ARCHITECTURE §6). Used by `imucal calibrate` and by stationd's
// worker, so the two can never drift apart.
//   factory: AINS + NLSQ (both need the table reference), evaluated against it;
//   land:     AINS (zero velocity, depth) + the legacy method (no reference needed); below
//             navigation grade legacy runs first and AINS linearises about its result (a unit far
//             from nominal is out of a filter's reach from zero, issue #21), and the result says
//             which of the two holds the rests (calib/pipeline/holding_method.hpp);
//   sea:      AINS (GNSS, depth) alone — the legacy method needs a still platform;
//   without an attitude reference the metrics are marked not evaluated, and the cross-check
//   compares the parameters both can observe.
#include <functional>
#include <optional>
#include <string>

#include "calib/ains/ains.hpp"
#include "calib/checks/crosscheck.hpp"
#include "calib/checks/evaluation.hpp"
#include "calib/checks/limit_check.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "calib/pipeline/holding_method.hpp"

namespace imucal::calib::pipeline {
using namespace calib::ains;
using namespace calib::checks;
using namespace calib::core;
using namespace calib::legacy;
using namespace calib::nlsq;

/// kAll: the setting's methods (factory: AINS + NLSQ; land: AINS + legacy; sea: AINS).
enum class MethodSelection { kAins, kNlsq, kLegacy, kAll };

struct PipelineOptions {
  MethodSelection methods = MethodSelection::kAll;
  AinsOptions ains;
  NlsqOptions nlsq;
  LegacyOptions legacy;
  EvaluationOptions evaluation;
  CrossCheckOptions crosscheck;
  /// Every method's result is checked (convergence, finiteness, datasheet envelope; the metrics
  /// where no cross-check looks at them). Its metric limits follow `crosscheck`'s.
  LimitCheckOptions limits;
  /// Land below navigation grade with AINS and legacy: when AINS holds the rests
  /// (holding_method.hpp).
  HoldingOptions holding;
  /// Sanity checks of the raw data (calib/checks/data_check.hpp): DataCheckError naming the symptom
  /// (stuck or clipped channel, wrong fixture orientation, swapped axes, unit not moved) instead of
  /// any result. Without `concurrent` they run first; with it, beside AINS.
  bool check_data = true;
  /// The two methods (and their evaluations) at the same time, the second on a thread of its own
  /// after the data checks, AINS meanwhile: they share only the read-only input, and the results
  /// are the same either way (issue #11).
  bool concurrent = true;
  /// Called with a short phase description ("AINS", "NLSQ", "evaluating AINS", ...) before each
  /// phase, so front ends can show progress. May be empty. Never called by two threads at once
  /// (with `concurrent`, the phases of the two methods interleave).
  std::function<void(const std::string&)> on_phase;
};

struct MethodOutcome {
  CalibrationResult result;
  EvaluationMetrics metrics;
};

struct PipelineResult {
  std::optional<MethodOutcome> ains;
  std::optional<MethodOutcome> nlsq;
  std::optional<MethodOutcome> legacy;
  std::optional<CrossCheckResult> crosscheck;  ///< only when two methods ran
  LimitCheckResult limits;                     ///< of every method that ran
  /// Why no second method can check this result ("" when one can, or one was not asked for): a
  /// sea run has AINS alone. Such a result is REVIEW in `imucal calibrate` as in the station.
  std::string unchecked_reason;
  /// Which method holds the rests, with both figures and why: set for a land run below navigation
  /// grade where AINS and legacy both ran (calib/pipeline/holding_method.hpp), unset otherwise.
  std::optional<HoldingMethod> holding;
  /// True when the legacy fit holds and AINS does not: the verdict and the active set rest on it.
  bool rests_on_legacy() const { return holding && holding->method == Method::kLegacy; }
  /// Good enough to store as good: every limit holds and, where two methods ran, they agree; a
  /// sea run never is (nothing independent checks it). Where the legacy fit holds and AINS does
  /// not, its own limits alone: AINS's failures and the cross-check's are reported, but a filter
  /// that cannot hold the rests does not judge the fit that does.
  bool pass() const {
    if (!unchecked_reason.empty()) return false;
    if (rests_on_legacy()) return limits_hold_for(Method::kLegacy);
    return limits.pass && (!crosscheck || crosscheck->pass);
  }
  /// No limit failure of method `m`.
  bool limits_hold_for(Method m) const;
};

/// Throws DataCheckError (an std::invalid_argument) when the raw data fail the sanity checks,
/// std::invalid_argument for NLSQ on a land/sea input (it needs the table reference,
/// paper §V) and whatever the methods throw for bad input.
PipelineResult run_calibration(const CalibrationInput& in, const PipelineOptions& opt = {});

}  // namespace imucal::calib::pipeline
