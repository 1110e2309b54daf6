#pragma once
// `stationctl show RUN_ID`: everything stored about a run. Read from stationd, else from the
// database read-only, or from the fleet store (--fleet).
#include <CLI/CLI.hpp>

#include "db/history/repository.hpp"
#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct ShowArgs {
  db::history::RunId run_id = 0;
};

CLI::App* add_show_command(CLI::App& app, ShowArgs& args);
int cmd_show(const Target& t, const ShowArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
