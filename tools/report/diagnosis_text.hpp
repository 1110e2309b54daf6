#pragma once
// The gap diagnosis as text for people: what `imucal diagnose DIR` and `stationctl diagnose RUN_ID`
// print, from the one JSON both get (db::archive::diagnosis_run_json), so the two commands print
// the same report (issue #49 item 4: stationctl printed its own, shorter table without column
// headers). In order: the run, the verdict and summary, the explained set step by step, the overall
// gap against the simulated twin, the rest samples' whiteness, the held-out gap, the candidate
// effects ranked in labelled columns, the segments with the largest gap, the calibration parameters
// that move, and where the gap remains.
#include <nlohmann/json.hpp>
#include <string>

namespace imucal::tools::report {

/// `diagnosis`: the JSON of db::archive::diagnosis_run_json (optionally with "run_id": the
/// station's run, named in the first line). A field it lacks (a diagnosis.json written before
/// "samples") is left out of the text, never guessed.
std::string diagnosis_report_text(const nlohmann::json& diagnosis);

}  // namespace imucal::tools::report
