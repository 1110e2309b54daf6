// Issue #52 item 1 and 3 over the fleet store: tests/db/fleet_truth_history.hpp's history (field
// run, reprocesses — one a chain —, station fault, abort, interruption, a unit's FAILED) written
// into a station's SQLite, replicated into a throw-away PostgreSQL, and stationweb started on the
// store as QA's read-only role. /fleet's verdicts, runs per day and distributions, for each
// setting and verdict filter, must equal the numbers computed from the rows by the rules of
// db/history/fleet_stats.hpp (tests/tools/fleet_truth_checks.hpp, as over the SQLite file), and
// /fleet's banner must say of each station what /signatures says.
#include <gtest/gtest.h>

#include <fstream>
#include <map>

#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/fleet_truth_history.hpp"
#include "tests/fleet/replicate_to_store.hpp"
#include "tests/support/pg_cluster.hpp"
#include "tests/tools/fleet_truth_checks.hpp"
#include "tests/tools/stationweb_process.hpp"
#include "tools/stationweb/httplib.hpp"

namespace imucal {
namespace {

using test_support::PgCluster;

class FleetTruth : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    pg_ = std::make_unique<PgCluster>();
    dir_ = std::make_unique<db::test::TempDir>();
    const std::string db = dir_->file("truth.sqlite");
    db::history::SqliteRepository repo(db);
    rows_ = db::test::write_truth_history(repo);
    test_support::replicate_to_store(repo, *pg_);
    const std::string pw = dir_->file("reader.pw");
    std::ofstream(pw) << PgCluster::kReaderPassword << "\n";
    web_ = std::make_unique<test_support::StationwebProcess>(
        std::string(IMUCAL_BIN_DIR) + "/stationweb", pg_->url("fleet_reader"),
        dir_->file("store.log"), std::vector<std::string>{"--password-file", pw});
  }
  static void TearDownTestSuite() {
    web_.reset();
    dir_.reset();
    pg_.reset();
  }
  static std::string get(const std::string& target) {
    httplib::Client c("127.0.0.1", web_->port());
    c.set_url_encode(false);
    c.set_read_timeout(30, 0);
    const auto r = c.Get(target.c_str());
    EXPECT_TRUE(r && r->status == 200) << target << (r ? "\n" + r->body.substr(0, 3000) : "");
    return r ? r->body : std::string();
  }

  static inline std::unique_ptr<PgCluster> pg_;
  static inline std::unique_ptr<db::test::TempDir> dir_;
  static inline std::vector<db::test::TruthRow> rows_;
  static inline std::unique_ptr<test_support::StationwebProcess> web_;
};

TEST_F(FleetTruth, TheStoreCountsFactoryRunsOnceEachCaptureAndStationFaultsApart) {
  test_support::expect_fleet_truth_under_every_filter(
      [](const std::string& target) { return get(target); }, rows_);
}

TEST_F(FleetTruth, TheStoresBannerAndSignaturesSayTheSameOfEveryStation) {
  test_support::expect_signatures_agree(get("/signatures"), get("/fleet"), rows_);
}

}  // namespace
}  // namespace imucal
