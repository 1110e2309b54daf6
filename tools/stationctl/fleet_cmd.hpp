#pragma once
// `stationctl fleet resync [--station-id ID]`: this station's share of the factory's fleet store
// rebuilt from its SQLite history (the config's [fleet], or --fleet URL with --station-id): every
// run stored; runs the store holds and this database does not (a replaced or restored database)
// are kept, set apart as station ID.previous-TIME, never deleted; safe while stationd runs.
#include <CLI/CLI.hpp>
#include <string>

#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

struct FleetArgs {
  std::string station_id;  ///< "" = the config's
};

/// `fleet` and its subcommand `resync`, which it returns.
CLI::App* add_fleet_commands(CLI::App& app, FleetArgs& args);
int cmd_fleet_resync(const Target& t, const FleetArgs& a, bool as_json);

}  // namespace imucal::tools::stationctl
