#pragma once
// A station's history replicated into the fleet store of a test's PostgreSQL cluster, as the
// stations' outbox senders would leave it, for the tests that read the store through stationweb.
#include <map>
#include <string>
#include <vector>

#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/support/pg_cluster.hpp"

namespace imucal::test_support {

/// Every run of `repo` upserted into `pg`'s fleet store (migrated first), one station id per
/// station name.
inline void replicate_to_store(const db::history::SqliteRepository& repo, const PgCluster& pg) {
  db::fleet::PgConnection w(
      db::fleet::parse_fleet_target(pg.url("fleet_writer"), PgCluster::kWriterPassword));
  db::fleet::migrate_fleet(w);
  std::map<std::string, std::vector<db::history::RunId>> by_station;
  for (const db::history::RunRecord& r : repo.recent_runs(0))
    by_station[r.station].push_back(r.run_id);
  for (const auto& [station, ids] : by_station)
    db::fleet::upsert_runs(w, station, repo.details_of(ids));
}

}  // namespace imucal::test_support
