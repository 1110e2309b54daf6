#pragma once
// `stationctl reprocess RUN_ID... [--wait] [--partial] [--gravity-mps2 G]`: stored runs
// recalibrated from their archives into new runs (needs the group); several runs (a flagged
// station's, issue #25) one after another, each followed to its end.
#include <CLI/CLI.hpp>
#include <optional>
#include <vector>

#include "db/history/repository.hpp"
#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct ReprocessArgs {
  std::vector<db::history::RunId> run_ids;  ///< one or several
  bool wait = false, partial = false;
  std::optional<double> gravity_mps2;  ///< the corrected surveyed gravity
};

CLI::App* add_reprocess_command(CLI::App& app, ReprocessArgs& args);
int cmd_reprocess(const Target& t, const ReprocessArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
