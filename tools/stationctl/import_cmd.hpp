#pragma once
// `stationctl import DIR [--wait]`: a field (land/sea) or other station's run archive added to its
// unit's history and calibrated with its setting (needs the group).
#include <CLI/CLI.hpp>
#include <string>

#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct ImportArgs {
  std::string dir;  ///< the run archive directory
  bool wait = false;
};

CLI::App* add_import_command(CLI::App& app, ImportArgs& args);
int cmd_import(const Target& t, const ImportArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
