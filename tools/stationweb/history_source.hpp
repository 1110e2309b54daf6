#pragma once
// Where stationweb reads from, behind one function: open_history(source). Today a source is the
// path of a station's SQLite history, opened read-only (db::SqliteRepository in QA mode and
// db::SqliteFleetStats, each its own read-only connection). The PostgreSQL fleet store plugs in
// here (a "postgresql://" URL) by returning its own db::Repository and db::FleetStats: the pages
// only see the two interfaces.
#include <memory>
#include <string>

#include "db/fleet_stats.hpp"
#include "db/repository.hpp"

namespace imucal::stationweb {

struct History {
  std::unique_ptr<db::Repository> repo;
  std::unique_ptr<db::FleetStats> stats;
  std::string label;  ///< what the pages say they show ("SQLite history /path/to/history.db")
};

/// Opens `source` read-only. Throws db::DbError (NotFound for a missing file, IncompatibleSchema,
/// Corrupt, ...) naming it, or std::invalid_argument for a source of a kind not supported yet.
History open_history(const std::string& source);

}  // namespace imucal::stationweb
