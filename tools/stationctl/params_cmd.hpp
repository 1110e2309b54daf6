#pragma once
// `stationctl params SN [--bare]`: the unit's active parameter set with 1-sigma (JSON for the INS)
// and, under "source", the run it comes from. Read from stationd, else from the database
// read-only, or from the fleet store (--fleet).
#include <CLI/CLI.hpp>
#include <string>

#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct ParamsArgs {
  std::string serial;
  bool bare = false;  ///< leave "source" out
};

CLI::App* add_params_command(CLI::App& app, ParamsArgs& args);
int cmd_params(const Target& t, const ParamsArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
