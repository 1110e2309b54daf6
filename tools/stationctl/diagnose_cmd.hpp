#pragma once
// `stationctl diagnose RUN_ID [--report OUTDIR]`: the sim-to-real gap diagnosis of a stored run,
// made by the daemon and kept with the run (needs the group); the report is written here, the same
// page as imucal diagnose's. Exits as `imucal diagnose` does: 0 consistent or explained, 3
// unexplained (a refusal, also 3, says so on stderr).
#include <CLI/CLI.hpp>
#include <string>

#include "db/history/repository.hpp"
#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct DiagnoseArgs {
  db::history::RunId run_id = 0;
  std::string report_dir;  ///< "" = no report
};

CLI::App* add_diagnose_command(CLI::App& app, DiagnoseArgs& args);
int cmd_diagnose(const Target& t, const DiagnoseArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
