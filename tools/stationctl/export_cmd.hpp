#pragma once
// `stationctl export --format csv|json|ndjson [--per-run] [--output FILE]`: the history streamed
// from the daemon as it reads the rows, or straight from the database when the daemon is down, or
// from the fleet store (--fleet); memory stays flat either way (issue #11). Where the bytes go:
// tools/stationctl/export_output.hpp.
#include <CLI/CLI.hpp>
#include <string>

#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct ExportArgs {
  std::string serial;  ///< only this unit
  std::string since;   ///< only runs started at or after
  std::string format;
  std::string output;  ///< "" = standard output
  std::string station;
  bool per_run = false;  ///< a row per run, the methods side by side (else per run and method)
};

CLI::App* add_export_command(CLI::App& app, ExportArgs& args);
int cmd_export(const Target& t, const ExportArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
