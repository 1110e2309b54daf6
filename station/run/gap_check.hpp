#pragma once
// The station's use of the sim-to-real gap diagnosis (calib/diagnosis/diagnosis.hpp, issue #8):
//  * check_gap: every calibrated run gets it in the worker, against its own NLSQ calibration, at
//    the station's false-alarm rate per run; a significant gap makes the run REVIEW, naming an
//    effect only when it explains the gap (DiagnosisOptions::min_shrinkage of the held-out gap);
//  * diagnose_archive: `stationctl diagnose RUN_ID` on a stored run's archive.
// The summary kept with the run is db::archive::diagnosis_summary_json (verdict, best effect with
// magnitude and σ, overall gap, held-out gap).
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"
#include "db/archive/run_archive.hpp"

namespace imucal::station::run {

struct GapCheck {
  nlohmann::json summary;    ///< stored with the run
  bool significant = false;  ///< the run departs from its model: never PASS, unless known
  /// Significant, and explained by the product's known effects alone (summary's
  /// "known_effects_only": true): kept with the run, not a REVIEW.
  bool known = false;
  std::string text;  ///< the diagnosis' one-sentence summary
};

/// A diagnosis that cannot run (a run too short for it) does not fail a calibration that
/// succeeded: it is stored as {"verdict": "not run", "reason": ...} and the cross-check decides.
/// `false_alarm_per_run`: the rate at which a run without any unmodelled effect is called
/// significant ([calibration] gap_false_alarm).
/// `known_effects`: the product's known effects ([calibration] known_effects).
GapCheck check_gap(calib::core::CalibrationInput in, const db::archive::RunArchive& ar,
                   const calib::core::ParamSet& nlsq_params, double false_alarm_per_run,
                   const std::vector<std::string>& known_effects = {});

/// The full diagnosis JSON of an archive directory (db::archive::diagnosis_run_json, the shape
/// imucal diagnose prints), plus "stored_summary" (what check_gap stores). Throws on input it
/// cannot use, naming it.
nlohmann::json diagnose_archive(const std::string& dir);

}  // namespace imucal::station::run
