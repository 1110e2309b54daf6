#include "tools/imucal/diagnose_cmd.hpp"

#include <filesystem>
#include <iostream>
#include <stdexcept>

#include "calib/ains/ains.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/gap_model.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/diagnosis_json.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/run_archive.hpp"
#include "tools/imucal/exit_codes.hpp"
#include "tools/report/diagnosis_report.hpp"
#include "tools/report/diagnosis_text.hpp"

namespace imucal::tools::imucal {
using namespace tools::report;

namespace {

std::vector<calib::effects::EffectId> parse_candidates(const std::string& list) {
  try {
    return calib::effects::parse_effect_list(list);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--candidates: ") + e.what());
  }
}

}  // namespace

CLI::App* add_diagnose_command(CLI::App& app, DiagnoseArgs& a) {
  auto* c = app.add_subcommand(
      "diagnose", "sim-to-real gap: where a run departs from the model, which effect explains it");
  c->add_option("dir", a.dir, "run archive directory")->required();
  c->add_flag("--json", a.json, "print one JSON object");
  c->add_option(
      "--report", a.report_dir,
      "also write OUTDIR/report.html (heat map, ranking, before/after) and OUTDIR/diagnosis.json");
  c->add_option(
      "--candidates", a.candidates,
      "comma-separated effects to consider (default: the whole catalogue; see imucal effects)");
  c->add_option("--grade", a.grade,
                "navigation|tactical|mems: the unit's grade instead of run.toml's [prior] grade "
                "(field runs: the rest detector; every run: how large an effect may plausibly be)")
      ->check(CLI::IsMember({"navigation", "tactical", "mems"}));
  c->add_option("--min-rest-s", a.min_rest_s,
                "field runs: the shortest rest kept, s (default: the detector's)")
      ->check(CLI::Range(0.5, 600.0));
  c->add_option("--first-rest-s", a.first_rest_s,
                "field runs: the first rest must last this long, s (default: the grade's rule, "
                "as calibrate)")
      ->check(CLI::Range(0.5, 600.0));
  return c;
}

namespace {

/// --report OUTDIR must be a directory or not exist yet (checked before any work).
void check_report_dir(const std::string& dir) {
  if (dir.empty()) return;
  std::error_code ec;
  if (std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
    throw std::invalid_argument("--report " + dir + ": exists and is not a directory");
}

/// OUTDIR/report.html and OUTDIR/diagnosis.json, each written atomically; OUTDIR created only now
/// that the diagnosis has succeeded.
void write_report(const std::string& dir, const nlohmann::json& j) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("--report " + dir + ": cannot create it: " + ec.message());
  db::archive::write_file_atomic(dir + "/diagnosis.json", j.dump(2) + "\n");
  db::archive::write_file_atomic(dir + "/report.html", diagnosis_report_html(j));
}

}  // namespace

int cmd_diagnose(const DiagnoseArgs& a) {
  const std::vector<calib::effects::EffectId> ids =
      parse_candidates(a.candidates);  // before any work
  check_report_dir(a.report_dir);
  db::archive::RunArchive ar = db::archive::read_archive(a.dir);
  if (!a.grade.empty()) ar.info.grade = *calib::core::parse_grade(a.grade);
  if (a.min_rest_s > 0.0) ar.info.min_rest_s = a.min_rest_s;
  if (a.first_rest_s > 0.0) ar.info.first_rest_s = a.first_rest_s;
  calib::diagnosis::DiagnosisInput in;
  in.cal = db::archive::to_calibration_input(ar);
  try {
    calib::diagnosis::GapModel::check_setting(in.cal);  // before calibrating it
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(a.dir + ": " + e.what());
  }
  if (ar.info.reference == db::archive::ReferenceKind::kTable)
    in.geometry = ar.info.table.geometry();
  // The model under test: a table run's NLSQ calibration; a land run's multi-position one, which
  // needs no prior beyond the grade's; a sea run's AINS (a rocking deck has no still rest for the
  // multi-position method). The diagnosis refits the base either way.
  const bool table_free = !in.cal.has_reference_attitude();
  const bool sea = in.cal.setting == calib::core::Setting::kSea;
  const char* method = sea ? "ains" : table_free ? "legacy" : "nlsq";
  const calib::core::CalibrationResult cal = sea          ? calib::ains::calibrate_ains(in.cal)
                                             : table_free ? calib::legacy::calibrate_legacy(in.cal)
                                                          : calib::nlsq::calibrate_nlsq(in.cal);
  calib::diagnosis::DiagnosisOptions opt;
  opt.candidates = ids;
  const calib::diagnosis::DiagnosisResult d = calib::diagnosis::diagnose(in, cal.params, opt);
  const nlohmann::json j = db::archive::diagnosis_run_json(d, a.dir, ar.info, in.cal, method);
  if (!a.report_dir.empty()) write_report(a.report_dir, j);
  // The text is rendered from the JSON, as stationctl diagnose renders the daemon's (issue #49
  // item 4: one report from the same code).
  std::cout << (a.json ? j.dump(2) + "\n" : diagnosis_report_text(j));
  return d.verdict == "unexplained" ? kExitReview : 0;
}

}  // namespace imucal::tools::imucal
