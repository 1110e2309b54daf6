#pragma once
// Which of a land run's two calibrations the verdict and the active parameter set rest on
// (issue #48 item 7, ARCHITECTURE §6 "Which method holds"). On land below navigation grade AINS
// and the legacy fit calibrate the unit from the same rests; the legacy fit minimises what those
// rests see (|f| = g at every rest, gravity carried across every move), the filter a model of the
// whole run. On four of five real MEMS recordings the filter leaves 1.8-5× the legacy fit's
// gravity residual at the rests (why is open; docs/validation/corpus.md): there it cannot stand
// as the unit's calibration, and a cross-check failure it causes says more about the filter than
// about the unit. Both sets are judged in-sample with the held-out check's rest figure
// (calib/checks/held_out_check.hpp) over the legacy fit's own rests: AINS holds while its residual
// is within a ratio of the legacy fit's; otherwise the legacy fit holds and the result says why,
// with both figures. Navigation grade, the factory and the sea are not judged (nullopt): AINS is
// the active set there, as before.
#include <cstddef>
#include <optional>
#include <string>

#include "calib/core/calibration_input.hpp"
#include "calib/legacy/legacy.hpp"

namespace imucal::calib::pipeline {
using namespace calib::core;
using namespace calib::legacy;

/// The estimators the calibration job runs.
enum class Method { kAins, kNlsq, kLegacy };
/// "ains", "nlsq", "legacy" (as CalibrationResult::method and the history spell them).
const char* method_name(Method m);

struct HoldingOptions {
  /// AINS holds a land run below navigation grade while its gravity-magnitude residual RMS over
  /// the rests is at most this many times the legacy fit's (issue #48 item 7: "within 1.5× the
  /// legacy fit's residuals on the same rests"). Must be positive and finite.
  double max_ains_to_legacy_rest_ratio = 1.5;
};

/// The judgement: both figures, the method that holds and why, for people.
struct HoldingMethod {
  Method method = Method::kAins;
  std::string reason;  ///< e.g. "AINS leaves 0.20 mg over the 40 rests against legacy's 0.11 mg …"
  std::size_t rests = 0;
  double ains_rest_rms_mps2 = 0.0;    ///< RMS of |mean f| − g over the rests, AINS's parameters
  double legacy_rest_rms_mps2 = 0.0;  ///< the same, the legacy fit's parameters
  double max_ratio = 1.5;             ///< HoldingOptions::max_ains_to_legacy_rest_ratio
};

/// nullopt unless `in` is a land run below navigation grade (the only case both run on the same
/// rests and the filter is known not to reach the fit there). `rests_as` gives the rests the
/// legacy fit averaged (its minimum length and trim). Throws std::invalid_argument for a ratio
/// that is not positive and finite.
std::optional<HoldingMethod> judge_holding_method(const CalibrationInput& in,
                                                  const CalibrationResult& ains,
                                                  const CalibrationResult& legacy,
                                                  const LegacyOptions& rests_as,
                                                  const HoldingOptions& options = {});

}  // namespace imucal::calib::pipeline
