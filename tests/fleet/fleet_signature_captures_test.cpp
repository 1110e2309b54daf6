// The station signatures' one result per capture (db/history/fleet_stats.hpp
// signature_stand_ins) in the fleet store: a real station's history (tests/data/qa_station_history,
// with an interrupted original whose reprocess was reprocessed again, and a partial reprocess)
// replicated into a throw-away PostgreSQL gives, through db::fleet::PgFleetStats, the AINS results
// of the same runs as the station's own file through db::history::SqliteFleetStats.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/pg_fleet_stats.hpp"
#include "db/history/sqlite_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"
#include "tests/fleet/replicate_to_store.hpp"
#include "tests/support/pg_cluster.hpp"

namespace imucal {
namespace {

using test_support::PgCluster;

TEST(FleetSignatureCaptures, TheStoreTakesTheResultsTheStationTakes) {
  const db::test::TempDir dir;
  const std::string path = dir.file("history.sqlite");
  std::filesystem::copy_file(
      std::string(IMUCAL_SOURCE_DIR) + "/tests/data/qa_station_history/history.sqlite", path);
  const PgCluster pg;
  {
    const db::history::SqliteRepository repo(path);
    test_support::replicate_to_store(repo, pg);
  }
  std::set<db::history::RunId> station, store;
  for (const auto& r : db::history::SqliteFleetStats(path).ains_results({}))
    station.insert(r.run_id);
  const db::fleet::PgFleetStats fleet(
      db::fleet::parse_fleet_target(pg.url("fleet_reader"), PgCluster::kReaderPassword));
  for (const auto& r : fleet.ains_results({})) store.insert(r.local_run_id);
  EXPECT_EQ(store, station);
  // The capture the daemon interrupted (21, reprocessed as 22, again as 23) is in both, by 22.
  EXPECT_TRUE(store.count(22) && !store.count(21) && !store.count(23));
  EXPECT_FALSE(store.count(11)) << "a partial archive's result";
}

}  // namespace
}  // namespace imucal
