#pragma once
// `stationctl [--fleet URL | --db FILE] stations [--setting S]`: the stations with runs, each with
// its units' outcomes (PASS, REVIEW, FAILED and the yield) and its own faults counted apart (issue
// #50), counted as stationweb's /fleet counts (db/history/fleet_stats.hpp): factory runs unless
// --setting land, sea or all, one capture once (a reprocessed run is stood for by its newest
// reprocess), every time;
// `stationctl [--fleet URL | --db FILE] stations --signatures [--trend]`: station signatures
// (issue #25), each station's departure from the fleet and the station errors it fits, for one
// window or period by period; exit 1 if a station is flagged (with --trend: in the newest period).
#include <CLI/CLI.hpp>
#include <string>

#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct StationsArgs {
  bool signatures = false, trend = false;
  std::string since, until;  ///< signatures: the window
  int period_days = 7;       ///< --trend
  double false_alarm = 1e-3;
  /// The list's setting: factory (default, as stationweb's /fleet), land, sea or all.
  std::string setting = "factory";
};

CLI::App* add_stations_command(CLI::App& app, StationsArgs& args);
/// The station list, or with --signatures or --trend the signatures.
int cmd_stations(const Target& t, const StationsArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
