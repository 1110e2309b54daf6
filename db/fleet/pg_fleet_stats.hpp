#pragma once
// The fleet pages' aggregates (db/history/fleet_stats.hpp) over the fleet store: computed by the
// server (GROUP BY, percentile_cont, stddev_samp), so a week of a million-run store sends one row
// per station. "Station" is the store's station id. Same definitions as
// db::history::SqliteFleetStats; every value bound. Thread safety: calls serialised on one
// connection.
#include <memory>

#include "db/fleet/fleet_url.hpp"
#include "db/history/fleet_stats.hpp"

namespace imucal::db::fleet {
using namespace db::history;

class PgFleetStats final : public FleetStats {
 public:
  /// Connects and checks the schema version, as FleetRepository does.
  explicit PgFleetStats(const FleetTarget& target);
  ~PgFleetStats() override;

  std::vector<StationDayCount> runs_per_station_day(const FleetFilter& filter) const override;
  std::vector<StationVerdictCounts> verdict_counts_per_station(
      const FleetFilter& filter) const override;
  std::vector<ParamSummary> param_distribution(int param_index,
                                               const FleetFilter& filter) const override;
  std::vector<RunId> table_run_members(RunId table_run_id) const override;
  std::vector<AinsResultRow> ains_results(const FleetFilter& filter) const override;
  std::vector<ReprocessLink> reprocess_links() const override;

  /// The distribution's statement ($1 the 1-based parameter index, $2 NULL, $3-$9 the filter:
  /// since, until, station, serial, setting, verdict, the superseded runs as bigint[]), for EXPLAIN
  /// in the benchmark.
  static std::string param_distribution_sql();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace imucal::db::fleet
