#include "tools/stationctl/diagnose_cmd.hpp"

#include <filesystem>

#include "db/archive/io_util.hpp"
#include "station/control/control_protocol.hpp"
#include "tools/report/diagnosis_report.hpp"
#include "tools/report/diagnosis_text.hpp"

namespace imucal::tools::stationctl {

namespace {

/// `diagnose` of a run whose gap no candidate explains: the exit code of imucal diagnose.
constexpr int kGapUnexplained = 3;

/// --report OUTDIR must be a directory or not exist yet (checked before the daemon works).
void check_report_dir(const std::string& dir) {
  std::error_code ec;
  if (!dir.empty() && std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
    throw Failure{kBadInput, "--report " + dir + ": exists and is not a directory"};
}

/// OUTDIR/diagnosis.json and OUTDIR/report.html of the diagnosis `d`.
void write_report(const std::string& dir, const json& d) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Failure{kUnavailable, "--report " + dir + ": " + ec.message()};
  try {
    db::archive::write_file_atomic(dir + "/diagnosis.json", d.dump(2) + "\n");
    db::archive::write_file_atomic(dir + "/report.html", tools::report::diagnosis_report_html(d));
  } catch (const std::exception& e) {
    throw Failure{kUnavailable, std::string("--report: ") + e.what()};
  }
}

}  // namespace

CLI::App* add_diagnose_command(CLI::App& app, DiagnoseArgs& a) {
  CLI::App* diagnose = app.add_subcommand(
      "diagnose", "sim-to-real gap diagnosis of a stored run, kept with the run (needs the group)");
  diagnose->add_option("RUN_ID", a.run_id, "run id")->required()->check(CLI::PositiveNumber);
  diagnose->add_option("--report", a.report_dir,
                       "also write OUTDIR/report.html and OUTDIR/diagnosis.json (as imucal "
                       "diagnose --report)");
  diagnose->fallthrough();
  return diagnose;
}

int cmd_diagnose(const Target& t, const DiagnoseArgs& a, bool as_json) {
  check_report_dir(a.report_dir);
  ControlClient client = connect_or_fail(t);
  const json d = call(client, station::control::cmd::kDiagnose, {{"run_id", a.run_id}});
  if (!a.report_dir.empty()) write_report(a.report_dir, d);
  // The report imucal diagnose prints, from the same JSON and the same code (issue #49 item 4).
  print_result(d, as_json, tools::report::diagnosis_report_text);
  return d.value("verdict", "") == "unexplained" ? kGapUnexplained : kOk;
}

}  // namespace imucal::tools::stationctl
