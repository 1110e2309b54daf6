#include "station/run/gap_check.hpp"

#include <algorithm>

#include "calib/diagnosis/diagnosis.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/diagnosis_json.hpp"

namespace imucal::station::run {

namespace {

calib::diagnosis::DiagnosisInput diagnosis_input(calib::core::CalibrationInput in,
                                                 const db::archive::RunArchive& ar) {
  calib::diagnosis::DiagnosisInput din;
  din.cal = std::move(in);
  if (ar.info.reference == db::archive::ReferenceKind::kTable)
    din.geometry = ar.info.table.geometry();
  return din;
}

/// Explained, and by the product's known effects alone.
bool is_known(const calib::diagnosis::DiagnosisResult& d,
              const std::vector<std::string>& known_effects) {
  if (d.verdict != "explained" || d.explained_by.empty()) return false;
  for (const std::string& name : d.explained_by)
    if (std::find(known_effects.begin(), known_effects.end(), name) == known_effects.end())
      return false;
  return true;
}

}  // namespace

GapCheck check_gap(calib::core::CalibrationInput in, const db::archive::RunArchive& ar,
                   const calib::core::ParamSet& nlsq_params, double false_alarm_per_run,
                   const std::vector<std::string>& known_effects) {
  GapCheck g;
  const calib::diagnosis::DiagnosisOptions opt =
      calib::diagnosis::diagnosis_options_for_false_alarm(false_alarm_per_run);
  try {
    const calib::diagnosis::DiagnosisResult d =
        calib::diagnosis::diagnose(diagnosis_input(std::move(in), ar), nlsq_params, opt);
    g.summary = db::archive::diagnosis_summary_json(d);
    g.significant = d.verdict != "consistent";
    g.text = d.summary;
    g.known = g.significant && is_known(d, known_effects);
    if (g.significant) g.summary["known_effects_only"] = g.known;
  } catch (const std::exception& e) {
    g.summary = {{"verdict", "not run"}, {"reason", e.what()}};
  }
  return g;
}

nlohmann::json diagnose_archive(const std::string& dir) {
  db::archive::RunArchive ar = db::archive::read_archive(dir);
  // The samples move into the input; ar keeps its info, all that is used below.
  const calib::diagnosis::DiagnosisInput din =
      diagnosis_input(db::archive::to_calibration_input(std::move(ar)), ar);
  const calib::core::CalibrationResult cal = calib::nlsq::calibrate_nlsq(din.cal);
  const calib::diagnosis::DiagnosisResult d = calib::diagnosis::diagnose(din, cal.params);
  // The shape imucal diagnose prints, so that stationctl diagnose prints the same report.
  nlohmann::json j = db::archive::diagnosis_run_json(d, dir, ar.info, din.cal, "nlsq");
  j["stored_summary"] = db::archive::diagnosis_summary_json(d);
  return j;
}

}  // namespace imucal::station::run
