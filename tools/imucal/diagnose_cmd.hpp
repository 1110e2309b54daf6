#pragma once
// `imucal diagnose DIR [--json] [--candidates NAME,...]`: the sim-to-real gap diagnosis
// (calib/diagnosis/diagnosis.hpp) of a run archive — simulated, recorded by stationd or assembled
// from another source's CSV files. The model it tests is the run's own calibration with the
// archive's declared noise: NLSQ on a table run; on a table-free (land) run the multi-position
// method, each rest's attitude then an unknown of the diagnosis (calib/diagnosis/gap_model.hpp).
#include <CLI/CLI.hpp>
#include <string>

namespace imucal::tools::imucal {

struct DiagnoseArgs {
  std::string dir;
  bool json = false;
  std::string candidates;     ///< comma-separated catalogue names; empty = all
  std::string report_dir;     ///< --report OUTDIR; empty = none
  std::string grade;          ///< --grade: instead of run.toml's [prior] grade; empty = run.toml's
  double min_rest_s = 0.0;    ///< --min-rest-s (field runs); 0 = run.toml's
  double first_rest_s = 0.0;  ///< --first-rest-s (field runs); 0 = run.toml's
};

/// Adds the subcommand to `app`, binding its options to `args`.
CLI::App* add_diagnose_command(CLI::App& app, DiagnoseArgs& args);
/// Runs it. Exit codes as the tool's: 0 consistent or explained, 3 unexplained (needs a look),
/// 1 bad input (std::exception propagates to main, which prints it).
int cmd_diagnose(const DiagnoseArgs& args);

}  // namespace imucal::tools::imucal
