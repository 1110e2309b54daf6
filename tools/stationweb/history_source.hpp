#pragma once
// Where stationweb reads from, behind one function: open_history(source). A source is the path of
// a station's SQLite history, opened read-only (db::history::SqliteRepository in QA mode and
// db::history::SqliteFleetStats, each its own read-only connection), or the PostgreSQL fleet
// store's URL (db::fleet::FleetRepository and db::fleet::PgFleetStats): the pages only see the two
// interfaces.
#include <functional>
#include <memory>
#include <string>

#include "db/history/fleet_stats.hpp"
#include "db/history/repository.hpp"

namespace imucal::tools::stationweb {

struct History {
  std::unique_ptr<db::history::Repository> repo;
  std::unique_ptr<db::history::FleetStats> stats;
  std::string label;  ///< what the pages say they show ("SQLite history /path/to/history.db")
  /// What a page must say about its source now, "" when nothing (issue #52 item 11): an SQLite
  /// file deleted or replaced since it was opened keeps being read through the open connections
  /// — the old data, without a word unless the page says so. Checked per request (one stat).
  std::function<std::string()> source_notice = [] { return std::string(); };
};

/// Opens `source` read-only: the path of a station's SQLite history, or the fleet store's
/// postgresql:// URL (with `password`, else libpq's PGPASSWORD / ~/.pgpass). Throws
/// db::history::DbError (NotFound for a missing file, IncompatibleSchema, Corrupt, IoError for a
/// store it cannot log in to, InvalidInput for a bad URL or a directory given as the file, ...)
/// naming it — a URL always redacted.
History open_history(const std::string& source, const std::string& password = {});

}  // namespace imucal::tools::stationweb
