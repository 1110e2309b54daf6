// The QA view and its aggregates over the fleet store (issue #24 item 4 with items 1 and 3): the
// same rows (tests/db/fleet_history.hpp, written into a station's SQLite and replicated station by
// station into a throw-away PostgreSQL) give the same numbers through db::fleet::PgFleetStats as
// through db::history::SqliteFleetStats (whose numbers tests/db/fleet_stats_test.cpp checks against
// the rows themselves), and stationweb over the fleet store shows the same fleet pages as over the
// SQLite file, the unit's history and trend with the store's values, a 404 for an unknown serial or
// run, and quotes and semicolons in every filter as data.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <tuple>

#include "db/fleet/fleet_repository.hpp"
#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "db/fleet/pg_fleet_stats.hpp"
#include "db/history/sqlite_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/fleet_history.hpp"
#include "tests/fleet/replicate_to_store.hpp"
#include "tests/support/html_tags.hpp"
#include "tests/support/pg_cluster.hpp"
#include "tests/tools/stationweb_process.hpp"
#include "tools/stationweb/httplib.hpp"

namespace imucal {
namespace {

using test_support::PgCluster;
using test_support::tags;

class FleetView : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    pg_ = std::make_unique<PgCluster>();
    dir_ = std::make_unique<db::test::TempDir>();
    db_ = dir_->file("history.sqlite");
    db::history::SqliteRepository repo(db_);
    db::test::write_fleet_history(repo, true);
    db::history::NewRun first = db::test::new_run("SN-T1", db::test::fleet_t0() + 3600000);
    first.station = "st-B";
    first.slot = "A";
    table_first_ = repo.create_run(first);
    db::history::NewRun second = first;
    second.serial = "SN-T2";
    second.slot = "B";
    second.table_run_id = table_first_;
    repo.create_run(second);
    test_support::replicate_to_store(repo, *pg_);
  }
  static void TearDownTestSuite() {
    dir_.reset();
    pg_.reset();
  }
  static db::fleet::FleetTarget reader() {
    return db::fleet::parse_fleet_target(pg_->url("fleet_reader"), PgCluster::kReaderPassword);
  }

  static inline std::unique_ptr<PgCluster> pg_;
  static inline std::unique_ptr<db::test::TempDir> dir_;
  static inline std::string db_;
  static inline db::history::RunId table_first_ = 0;
};

std::vector<db::history::FleetFilter> filters() {
  const db::history::TimestampMs day = 86400000, t0 = db::test::fleet_t0();
  std::vector<db::history::FleetFilter> out(7);
  out[1].since_ms = t0 + day;
  out[1].until_ms = t0 + 4 * day;
  out[2].station = "st-B";
  out[3].serial = "SN-3";
  out[4].since_ms = t0 + 2 * day;
  out[5] = out[1];
  out[5].station = "st-A";
  out[5].serial = "SN-2";
  out[6].station = "x'; DROP TABLE runs; --";
  return out;
}

TEST_F(FleetView, TheStoresAggregatesEqualTheStationsForTheSameRows) {
  const db::history::SqliteFleetStats sqlite(db_);
  const db::fleet::PgFleetStats fleet(reader());
  EXPECT_EQ(sqlite.runs_per_station_day({}).size(), 16u) << "the rows are there to compare";
  for (const db::history::FleetFilter& f : filters()) {
    const auto a = sqlite.runs_per_station_day(f), b = fleet.runs_per_station_day(f);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].station, b[i].station);
      EXPECT_EQ(a[i].day, b[i].day);
      EXPECT_EQ(a[i].runs, b[i].runs);
    }
    const auto va = sqlite.verdict_counts_per_station(f), vb = fleet.verdict_counts_per_station(f);
    ASSERT_EQ(va.size(), vb.size());
    for (std::size_t i = 0; i < va.size(); ++i) {
      EXPECT_EQ(va[i].station, vb[i].station);
      // Issue #50: both backends apply the same rule to whose each end was.
      EXPECT_EQ(
          std::vector<std::int64_t>({va[i].pass, va[i].review, va[i].failed, va[i].station_fault,
                                     va[i].aborted, va[i].interrupted, va[i].live}),
          std::vector<std::int64_t>({vb[i].pass, vb[i].review, vb[i].failed, vb[i].station_fault,
                                     vb[i].aborted, vb[i].interrupted, vb[i].live}))
          << va[i].station;
    }
    for (int p = 0; p < calib::core::ParamSet::kSize; ++p) {
      const auto da = sqlite.param_distribution(p, f), dp = fleet.param_distribution(p, f);
      ASSERT_EQ(da.size(), dp.size()) << calib::core::param_info(p).name;
      for (std::size_t i = 0; i < da.size(); ++i) {
        const double tol = 1e-12 * std::max(std::abs(da[i].min), std::abs(da[i].max));
        EXPECT_EQ(da[i].station, dp[i].station);
        EXPECT_EQ(da[i].count, dp[i].count) << calib::core::param_info(p).name;
        EXPECT_NEAR(da[i].mean, dp[i].mean, tol);
        EXPECT_NEAR(da[i].std_dev, dp[i].std_dev, tol);
        EXPECT_EQ(da[i].min, dp[i].min);
        EXPECT_NEAR(da[i].q1, dp[i].q1, tol);
        EXPECT_NEAR(da[i].median, dp[i].median, tol);
        EXPECT_NEAR(da[i].q3, dp[i].q3, tol);
        EXPECT_EQ(da[i].max, dp[i].max);
      }
    }
  }
  // The AINS results for the station signatures: the same results, the store's ids aside.
  for (const db::history::FleetFilter& f : filters()) {
    auto a = sqlite.ains_results(f), b = fleet.ains_results(f);
    ASSERT_EQ(a.size(), b.size());
    // Each in its own ids' order; compared by what the runs are.
    auto by_run = [](const db::history::AinsResultRow& x, const db::history::AinsResultRow& y) {
      return std::tie(x.station, x.started_at_ms, x.serial) <
             std::tie(y.station, y.started_at_ms, y.serial);
    };
    std::sort(a.begin(), a.end(), by_run);
    std::sort(b.begin(), b.end(), by_run);
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].station, b[i].station);
      EXPECT_EQ(a[i].serial, b[i].serial);
      EXPECT_EQ(a[i].started_at_ms, b[i].started_at_ms);
      EXPECT_EQ(a[i].value.to_vector(), b[i].value.to_vector());
      EXPECT_EQ(a[i].sigma.to_vector(), b[i].sigma.to_vector());
      // The station's own id, which its stationctl reprocesses by: the SQLite id it came from.
      EXPECT_EQ(a[i].local_run_id, a[i].run_id);
      EXPECT_EQ(b[i].local_run_id, a[i].run_id);
    }
  }
  EXPECT_FALSE(sqlite.ains_results({}).empty());
  // A table run's members, by the store's ids.
  const db::fleet::FleetRepository repo(reader());
  const auto b = repo.station_runs("st-B", std::string("SN-T1"), 0);
  ASSERT_EQ(b.size(), 1u);
  const auto members = fleet.table_run_members(b[0].run_id);
  ASSERT_EQ(members.size(), 2u);
  EXPECT_EQ(repo.show(members[1]).run.serial, "SN-T2");
  EXPECT_TRUE(fleet.table_run_members(99999999).empty());
}

/// The fleet page's numbers as the page carries them, keyed by what they count.
std::map<std::string, std::string> fleet_numbers(const std::string& html) {
  std::map<std::string, std::string> out;
  using test_support::section;
  for (auto& c : tags(section(html, "runs-per-day", "</table>"), "<td class='num' data-station"))
    out["day " + c["data-station"] + " " + c["data-day"]] = c["data-runs"];
  for (auto& v : tags(section(html, "verdicts", "</table>"), "<tr data-station"))
    for (const char* k : {"data-pass", "data-review", "data-failed", "data-station-fault",
                          "data-aborted", "data-interrupted", "data-live", "data-unit-outcomes"})
      out["verdict " + v["data-station"] + " " + k] = v[k];
  for (auto& d : tags(section(html, "distribution", "</table>"), "<tr data-station"))
    for (const char* k : {"data-count", "data-min", "data-max"})
      out["param " + d["data-station"] + " " + k] = d[k];
  return out;
}

std::string get(int port, const std::string& target, int& status) {
  httplib::Client c("127.0.0.1", port);
  c.set_url_encode(false);
  c.set_read_timeout(30, 0);
  const auto r = c.Get(target.c_str());
  status = r ? r->status : -1;
  return r ? r->body : std::string();
}

TEST_F(FleetView, StationwebOverTheStoreShowsWhatItShowsOverTheStationsFile) {
  const std::string bin = std::string(IMUCAL_BIN_DIR) + "/stationweb";
  const std::string pw = dir_->file("reader.pw");
  std::ofstream(pw) << PgCluster::kReaderPassword << "\n";
  test_support::StationwebProcess local(bin, db_, dir_->file("local.log"));
  test_support::StationwebProcess store(bin, pg_->url("fleet_reader"), dir_->file("store.log"),
                                        {"--password-file", pw});
  int s1 = 0, s2 = 0;
  for (const std::string q :
       {"/fleet?since=2024-03-02&until=2024-03-04&param=gyro_bias_radps%5B2%5D",
        "/fleet?param=table_misalignment_rad%5B1%5D",
        "/fleet?station=st-B&param=accel_M%5B0%5D%5B1%5D",
        "/fleet?serial=SN-2&since=2024-03-01T06:00Z"}) {
    const auto a = fleet_numbers(get(local.port(), q, s1));
    const auto b = fleet_numbers(get(store.port(), q, s2));
    EXPECT_EQ(s1, 200);
    EXPECT_EQ(s2, 200) << q;
    EXPECT_FALSE(a.empty()) << q;
    EXPECT_EQ(a, b) << q;
  }
  // The unit page: the store's history of the serial, every trend point its AINS value.
  const db::fleet::FleetRepository repo(reader());
  const std::string unit = get(store.port(), "/unit/SN-3", s2);
  ASSERT_EQ(s2, 200);
  const auto rows = tags(test_support::section(unit, "history", "</table>"), "<tr class='run'");
  EXPECT_EQ(rows.size(), repo.history("SN-3").size());
  const db::history::RunId newest = repo.history("SN-3").front().run_id;
  const std::string run = get(store.port(), "/run/" + std::to_string(newest), s2);
  EXPECT_EQ(s2, 200);
  EXPECT_NE(run.find("SN-3"), std::string::npos);
  EXPECT_NE(run.find(repo.show(newest).run.archive_path), std::string::npos);
  // Unknown serial and run: 404 with a message; quotes and semicolons: data.
  EXPECT_NE(get(store.port(), "/unit/SN-NONE", s2).find("SN-NONE"), std::string::npos);
  EXPECT_EQ(s2, 404);
  get(store.port(), "/run/99999999", s2);
  EXPECT_EQ(s2, 404);
  const std::size_t before = repo.total_run_count();
  for (const std::string q : {"/fleet?station=x%27%3B%20DROP%20TABLE%20runs%3B%20--",
                              "/fleet?serial=x%27%3B%20DROP%20TABLE%20runs%3B%20--",
                              "/unit/x%27%3B%20DROP%20TABLE%20runs%3B%20--"}) {
    get(store.port(), q, s2);
    EXPECT_TRUE(s2 == 200 || s2 == 400 || s2 == 404) << q << " " << s2;
  }
  EXPECT_EQ(repo.total_run_count(), before);
  // The server restarted under it (SIGKILL): the next page is served from a new connection.
  pg_->kill9();
  pg_->start();
  get(store.port(), "/unit/SN-3", s2);
  EXPECT_EQ(s2, 200) << "stationweb outlives a restart of the fleet store";
  get(store.port(), "/fleet?param=gyro_bias_radps%5B2%5D", s2);
  EXPECT_EQ(s2, 200);
  EXPECT_EQ(repo.history("SN-3").size(), rows.size());
  // Its log names the store without the password.
  std::ifstream log(dir_->file("store.log"));
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find(PgCluster::kReaderPassword), std::string::npos);
}

}  // namespace
}  // namespace imucal
