// Issue #52's audit rules in the fleet store: a real station's history
// (tests/data/qa_station_history, with an interrupted original whose reprocess was reprocessed
// again, a partial reprocess and two imported land runs) replicated into a throw-away PostgreSQL
// gives, through db::fleet::PgFleetStats, what the station's own file gives through
// db::history::SqliteFleetStats: the signatures' AINS results of the same runs (one per capture,
// signature_stand_ins), the verdicts of a comma list of verdicts, and a frame-dependent parameter's
// distribution over housing-frame results only.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <set>
#include <tuple>

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

class FleetAuditedHistory : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<db::test::TempDir>();
    path_ = dir_->file("history.sqlite");
    std::filesystem::copy_file(
        std::string(IMUCAL_SOURCE_DIR) + "/tests/data/qa_station_history/history.sqlite", path_);
    pg_ = std::make_unique<PgCluster>();
    const db::history::SqliteRepository repo(path_);
    test_support::replicate_to_store(repo, *pg_);
  }
  static void TearDownTestSuite() {
    pg_.reset();
    dir_.reset();
  }
  static db::fleet::PgFleetStats fleet_stats() {
    return db::fleet::PgFleetStats(
        db::fleet::parse_fleet_target(pg_->url("fleet_reader"), PgCluster::kReaderPassword));
  }
  static inline std::unique_ptr<db::test::TempDir> dir_;
  static inline std::string path_;
  static inline std::unique_ptr<PgCluster> pg_;
};

TEST_F(FleetAuditedHistory, TheStoreTakesTheSignatureResultsTheStationTakes) {
  std::set<db::history::RunId> station, store;
  for (const auto& r : db::history::SqliteFleetStats(path_).ains_results({}))
    station.insert(r.run_id);
  const db::fleet::PgFleetStats fleet = fleet_stats();
  for (const auto& r : fleet.ains_results({})) store.insert(r.local_run_id);
  EXPECT_EQ(store, station);
  // The capture the daemon interrupted (21, reprocessed as 22, again as 23) is in both, by 22.
  EXPECT_TRUE(store.count(22) && !store.count(21) && !store.count(23));
  EXPECT_FALSE(store.count(11)) << "a partial archive's result";
}

TEST_F(FleetAuditedHistory, CommaVerdictsAndAFrameDependentDistributionAreTheStations) {
  const db::history::SqliteFleetStats station(path_);
  const db::fleet::PgFleetStats fleet = fleet_stats();
  db::history::FleetFilter f;
  f.verdict = "PASS,REVIEW";
  const auto a = station.verdict_counts_per_station(f), b = fleet.verdict_counts_per_station(f);
  ASSERT_EQ(a.size(), 1u);
  ASSERT_EQ(b.size(), 1u);
  EXPECT_GT(a[0].pass, 0);
  EXPECT_GT(a[0].review, 0);
  EXPECT_EQ(a[0].failed, 0);
  EXPECT_EQ(std::make_tuple(b[0].pass, b[0].review, b[0].failed, b[0].aborted),
            std::make_tuple(a[0].pass, a[0].review, a[0].failed, a[0].aborted));
  f = {};
  f.setting = std::nullopt;  // every setting: the two land runs' results are in another frame
  const int m01 = db::history::param_index("accel_M[0][1]");
  const auto da = station.param_distribution(m01, f), db = fleet.param_distribution(m01, f);
  ASSERT_EQ(da.size(), 1u);
  ASSERT_EQ(db.size(), 1u);
  EXPECT_EQ(da[0].other_frame, 2) << "the two imported land runs";
  EXPECT_EQ(db[0].count, da[0].count);
  EXPECT_EQ(db[0].other_frame, da[0].other_frame);
  EXPECT_NEAR(db[0].mean, da[0].mean, 1e-12 * std::abs(da[0].mean) + 1e-15);
}

}  // namespace
}  // namespace imucal
