#pragma once
// db::history::FleetStats over one station's SQLite history (db/history/SCHEMA.md), for
// stationweb's fleet pages.
//
// Its own connection, always read-only (SQLITE_OPEN_READONLY): it never creates, migrates or
// writes, and refuses a file whose schema version is not this software's (as SqliteRepository in
// read-only mode does). Every value is bound to a prepared statement (named parameters); the SQL
// text is assembled from constant fragments only, one WHERE clause per combination of the filters
// given, so that a time range uses the runs_by_time index and a serial runs_by_unit_time, and no
// "? IS NULL OR" disjunction hides them from the planner. The parameter's value is read with
// SQLite's json_extract from calibrations.params_json of the AINS row, its JSON path bound too.
//
// Thread safety: calls are serialised by an internal mutex.
#include <memory>
#include <string>

#include "db/history/fleet_stats.hpp"

namespace imucal::db::history {

class SqliteFleetStats final : public FleetStats {
 public:
  /// Opens `path` read-only. Throws NotFound (no file), IncompatibleSchema, Corrupt, IoError, each
  /// naming the path.
  explicit SqliteFleetStats(const std::string& path);
  ~SqliteFleetStats() override;
  SqliteFleetStats(const SqliteFleetStats&) = delete;
  SqliteFleetStats& operator=(const SqliteFleetStats&) = delete;

  std::vector<StationDayCount> runs_per_station_day(const FleetFilter& filter) const override;
  std::vector<StationVerdictCounts> verdict_counts_per_station(
      const FleetFilter& filter) const override;
  std::vector<ParamSummary> param_distribution(int param_index,
                                               const FleetFilter& filter) const override;
  std::vector<RunId> table_run_members(RunId table_run_id) const override;
  std::vector<AinsResultRow> ains_results(const FleetFilter& filter) const override;
  std::vector<ReprocessLink> reprocess_links() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace imucal::db::history
