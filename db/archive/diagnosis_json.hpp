#pragma once
// The gap diagnosis (calib/diagnosis/diagnosis.hpp) as JSON: what `imucal diagnose --json` prints,
// what the HTML report embeds and what the station keeps with a run. One object:
//   {"verdict": "consistent"|"explained"|"unexplained", "summary": "...",
//    "best": null | {"effect", "magnitude", "sigma", "unit", "parameters": [...]},
//    "second": null | {...}, "ambiguous": [names], "explained_by": [names],
//    "steps": [{"effect", "magnitude", "sigma", "unit", "p_value", "gap_after", "held_out_after",
//               "note", "parameters"}]   (the explained set in the order chosen, sizes from its
//               joint fit),
//    "candidates": [{"effect", "score", "lr", "k", "p_value", "bic_gain", "magnitude", "sigma",
//                    "unit", "separable", "significant", "note", "held_out_gap",
//                    "max_correlation", "confounded_with", "parameters"}, ...],   (ranked)
//    "held_out": {"gap_before", "gap_after", "gap_after_pair", "shrinkage"},
//    "overall": {"chi2", "dof", "gap", "expected", "sigma", "p_value", "gap_after_best"},
//    "segments": [{"label", "kind", "number", "t0_s", "t1_s", "outer_deg", "inner_deg", "nis",
//                  "nis_expected", "p_value", "z": {"accel_x", ...}, "residual_si": {...}}],
//    "moved_parameters": [...], "remaining": [{"where", "z"}], "runtime_s"}
// Parameters are in human units (the catalogue's), each with its unit; "score" is the BIC gain.
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "db/archive/run_archive.hpp"

namespace imucal::db::archive {

nlohmann::json diagnosis_to_json(const calib::diagnosis::DiagnosisResult& d);

/// A run archive's diagnosis: diagnosis_to_json plus what was diagnosed and how — "archive" (the
/// directory), "serial", "sequence", "setting", "grade", "table_free", "base_calibration" (the
/// model under test: "nlsq", "legacy" or "ains") and "samples" (IMU samples). What `imucal diagnose
/// --json` prints and the station's `diagnose` answers (then with "run_id"), one shape from one
/// function so that both print the same report (tools/report/diagnosis_text.hpp, issue #49 item 4).
nlohmann::json diagnosis_run_json(const calib::diagnosis::DiagnosisResult& d,
                                  const std::string& archive, const RunInfo& info,
                                  const calib::core::CalibrationInput& in,
                                  const std::string& base_calibration);

/// The summary kept with a station run (runs.diagnosis_json): {"verdict", "summary", "best",
/// "second", "ambiguous", "explained_by", "steps" (without parameters), "overall": {"gap",
/// "expected", "sigma", "p_value"}, "held_out": {...}}.
nlohmann::json diagnosis_summary_json(const calib::diagnosis::DiagnosisResult& d);

/// The effects a diagnosis found (its steps' deterministic effects, sizes from their joint fit; or,
/// in a diagnosis without steps, its "best" and "second"), back in SI: what `imucal calibrate
/// --compensate` removes from a run before calibrating it.
struct DiagnosedEffects {
  calib::effects::Effects effects;
  std::vector<std::string> names;  ///< "gyro_g_sensitivity = 686 deg/h/g", one per effect
};
/// Reads them from a diagnosis JSON (diagnose --json, or --report's diagnosis.json); `origin`
/// names it in errors. Throws std::invalid_argument naming the file and field when it is not a
/// diagnosis, names no effect, or a parameter is missing.
DiagnosedEffects diagnosed_effects(const nlohmann::json& j, const std::string& origin);

}  // namespace imucal::db::archive
