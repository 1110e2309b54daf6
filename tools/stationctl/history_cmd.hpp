#pragma once
// `stationctl history [SN]`: the runs of a unit, newest first; without SN the newest runs of every
// unit. Read from stationd, else from the database read-only, or from the fleet store (--fleet).
#include <CLI/CLI.hpp>
#include <cstddef>
#include <string>

#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct HistoryArgs {
  std::string serial;  ///< "" = every unit
  std::size_t limit = 0;
  std::string station;
};

CLI::App* add_history_command(CLI::App& app, HistoryArgs& args);
int cmd_history(const Target& t, const HistoryArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
