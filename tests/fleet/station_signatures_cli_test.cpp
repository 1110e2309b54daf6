// `stationctl stations --signatures` (issue #25) as QA runs it: a simulated fleet's week stored
// in a history as its stations would have stored it (tools/fleetsim write_history: the real
// simulator, the station's pipeline with both methods and the cross-check), read from the SQLite
// file (--db) and from the fleet store it is replicated to (--fleet): the gravity station, the
// non-orthogonal table and the turned fixture flagged with their cause and advice, the runs they
// touch (by the station's own ids too) and what to do with them (the gravity station's: the
// reprocess command), no other station; exit 1 when one is flagged; bad windows refused. And
// stationweb over the same file: the /fleet page opens with the same three flagged, /signatures
// shows them with the command, rendered by headless Chromium without a console message (its
// screenshot is the README's).
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "calib/core/conventions.hpp"
#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/fleet_url.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "tests/db/history_fixtures.hpp"
#include "tests/support/headless_chromium.hpp"
#include "tests/support/html_tags.hpp"
#include "tests/support/pg_cluster.hpp"
#include "tests/support/run_command.hpp"
#include "tests/tools/stationweb_process.hpp"
#include "tools/fleetsim/fleet_sim.hpp"
#include "tools/stationweb/httplib.hpp"

using namespace imucal;
using nlohmann::json;
using test_support::run_command;

namespace {

constexpr std::size_t kGravity = 2, kFixture = 5, kNonorth = 8;

class SignaturesCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new db::test::TempDir();
    db_ = dir_->file("fleet-week.sqlite");
    tools::fleetsim::FleetSpec spec = tools::fleetsim::sound_fleet(10, 20.0 * kArcsecToRad, 77);
    spec.units_per_station = 6;
    spec.stations[kGravity].gravity_error_mps2 = 50.0 * kMicroG_mps2;
    spec.stations[kNonorth].nonorthogonality_rad = 10.0 * kArcsecToRad;
    spec.stations[kFixture].fixture_rad = Eigen::Vector3d(180.0 * kArcsecToRad, 0, 0);
    db::history::SqliteRepository repo(db_);
    ids_ = tools::fleetsim::write_history(spec, repo,
                                          db::history::parse_time_utc("2026-11-16T06:00:00Z"));
  }
  static void TearDownTestSuite() { delete dir_; }

  static json signatures(const std::string& source, int& code) {
    const auto r = run_command(std::string(IMUCAL_BIN_DIR) + "/stationctl " + source +
                               " stations --signatures --json 2>/dev/null");
    code = r.code;
    return json::parse(r.out);
  }

  static void expect_the_three_flagged(const json& report) {
    ASSERT_EQ(report["stations"].size(), 10u) << report.dump(1);
    for (std::size_t s = 0; s < 10; ++s) {
      const json& st = report["stations"][s];
      SCOPED_TRACE(st["station"].get<std::string>());
      if (s != kGravity && s != kNonorth && s != kFixture) {
        EXPECT_FALSE(st["flagged"].get<bool>()) << st.dump(1);
        continue;
      }
      ASSERT_TRUE(st["flagged"].get<bool>()) << st.dump(1);
      const json& alarm = st["alarm"];
      const bool gravity = s == kGravity;
      EXPECT_EQ(alarm["effect"], gravity         ? "gravity_error"
                                 : s == kNonorth ? "table_nonorthogonality"
                                                 : "fixture_rotation_x");
      const std::string cause = alarm["cause"];
      EXPECT_NE(cause.find(gravity         ? "check the surveyed gravity of this site"
                           : s == kNonorth ? "check the squareness of this table's axes"
                                           : "check how the fixture sits on the platform"),
                std::string::npos)
          << cause;
      const double truth = gravity ? 50.0 : s == kNonorth ? 10.0 : 180.0;  // µg, arcsec
      EXPECT_LT(std::abs(alarm["size"].get<double>() - truth), 4 * alarm["sigma"].get<double>());
      EXPECT_EQ(st["run_ids"].size(), 7u) << "the station's six units and the golden unit's visit";
      EXPECT_EQ(st["local_run_ids"].size(), 7u);
      // Only a wrong setting is corrected by reprocessing; a fault in the data is not.
      EXPECT_EQ(st["remedy"]["reprocess"].get<bool>(), gravity) << st["remedy"].dump();
    }
  }

  static inline db::test::TempDir* dir_ = nullptr;
  static inline std::string db_;
  static inline std::vector<db::history::RunId> ids_;
};

}  // namespace

TEST_F(SignaturesCli, FromTheStationsHistoryTheThreeFaultyStationsAreFlaggedWithTheirCause) {
  ASSERT_EQ(ids_.size(), 70u);
  int code = 0;
  const json report = signatures("--db " + db_, code);
  EXPECT_EQ(code, 1) << "a flagged station is exit 1";
  expect_the_three_flagged(report);
  const json& g = report["stations"][kGravity];
  std::vector<db::history::RunId> expected(ids_.begin() + 14,
                                           ids_.begin() + 21);  // station 2's jobs
  EXPECT_EQ(g["run_ids"].get<std::vector<db::history::RunId>>(), expected);
  EXPECT_EQ(g["local_run_ids"], g["run_ids"]) << "a station's own history: its own ids";
  EXPECT_EQ(g["remedy"]["command"], "stationctl reprocess 15 16 17 18 19 20 21 --gravity-mps2 G");
  // The text QA reads: the cause with its size, the advice, the runs.
  const auto text = run_command(std::string(IMUCAL_BIN_DIR) + "/stationctl --db " + db_ +
                                " stations --signatures 2>&1");
  EXPECT_NE(text.out.find("FLAGGED (the others' z given the errors named)\n    common "
                          "accelerometer scale +"),
            std::string::npos)
      << text.out;
  // The fixture station's other candidates, given the fixture: nothing left (each alone would
  // echo the 180″ through overlapping responses).
  const json& fx = report["stations"][kFixture];
  EXPECT_EQ(fx["alarms"].size(), 1u) << fx.dump(1);
  for (const json& f : fx["fits_given_alarms"])
    EXPECT_LT(std::abs(f["z"].get<double>()), report["z_threshold"].get<double>()) << f.dump();
  EXPECT_NE(text.out.find("runs it touches (7):"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("reprocess the runs at st-02 with G the new survey"), std::string::npos)
      << text.out;
}

TEST_F(SignaturesCli, FromTheFleetStoreTheSameStationsAreFlagged) {
  test_support::PgCluster pg;
  {
    namespace fl = db::fleet;
    fl::PgConnection w(
        fl::parse_fleet_target(pg.url("fleet_writer"), test_support::PgCluster::kWriterPassword));
    fl::migrate_fleet(w);
    db::history::SqliteOptions ro;
    ro.read_only = true;
    const db::history::SqliteRepository repo(db_, ro);
    std::map<std::string, std::vector<db::history::RunId>> by_station;
    for (const db::history::RunRecord& r : repo.recent_runs(0))
      by_station[r.station].push_back(r.run_id);
    for (const auto& [station, ids] : by_station) fl::upsert_runs(w, station, repo.details_of(ids));
  }
  const std::string pw = dir_->file("reader.pw");
  std::ofstream(pw) << test_support::PgCluster::kReaderPassword << "\n";
  int code = 0;
  const json report =
      signatures("--fleet " + pg.url("fleet_reader") + " --fleet-password-file " + pw, code);
  EXPECT_EQ(code, 1);
  expect_the_three_flagged(report);
  // The store numbers runs its own way; the reprocess command names the station's ids.
  const json& g = report["stations"][kGravity];
  const std::vector<db::history::RunId> expected(ids_.begin() + 14, ids_.begin() + 21);
  EXPECT_EQ(g["local_run_ids"].get<std::vector<db::history::RunId>>(), expected);
  EXPECT_EQ(g["remedy"]["command"], "stationctl reprocess 15 16 17 18 19 20 21 --gravity-mps2 G");
}

TEST_F(SignaturesCli, AWindowThatEndsBeforeItStartsOrHasNoRunsIsClear) {
  const std::string bin = std::string(IMUCAL_BIN_DIR) + "/stationctl --db " + db_;
  const auto bad =
      run_command(bin + " stations --signatures --since 2026-11-20 --until 2026-11-10 2>&1");
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("since must be earlier than until"), std::string::npos) << bad.out;
  const auto empty =
      run_command(bin + " stations --signatures --since 2020-01-01 --until 2020-01-07 2>&1");
  EXPECT_EQ(empty.code, 0) << empty.out;
  EXPECT_NE(empty.out.find("no factory AINS results in this window"), std::string::npos)
      << empty.out;
}

TEST_F(SignaturesCli, TheWebViewFlagsTheSameStationsWithTheirCauseAndRendersCleanly) {
  test_support::StationwebProcess web(std::string(IMUCAL_BIN_DIR) + "/stationweb", db_,
                                      dir_->file("stationweb.log"));
  httplib::Client client("127.0.0.1", web.port());
  client.set_read_timeout(60, 0);
  const auto r = client.Get("/signatures");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  for (const char* st : {"st-02", "st-05", "st-08"})
    EXPECT_NE(r->body.find(std::string("data-station='") + st + "' data-flagged='1'"),
              std::string::npos)
        << st;
  std::size_t flagged = 0;
  for (const auto& row : test_support::tags(r->body, "<tr data-station="))
    flagged += row["data-flagged"] == "1" ? 1 : 0;
  EXPECT_EQ(flagged, 3u);
  EXPECT_NE(r->body.find("stationctl reprocess 15 16 17 18 19 20 21 --gravity-mps2 G"),
            std::string::npos);
  // The fleet page opens with the same three, each with its cause.
  const auto fleet = client.Get("/fleet");
  ASSERT_TRUE(fleet);
  ASSERT_EQ(fleet->status, 200);
  EXPECT_NE(fleet->body.find("id='signature-banner' class='alarm' data-flagged='3'"),
            std::string::npos)
      << fleet->body.substr(0, 3000);
  for (const char* st : {"st-02", "st-05", "st-08"})
    EXPECT_NE(fleet->body.find(std::string("<li data-station='") + st + "'>"), std::string::npos)
        << st;
  EXPECT_NE(r->body.find("data-station='st-02' data-effect='gravity_error'"), std::string::npos);
  EXPECT_NE(r->body.find("check the surveyed gravity of this site"), std::string::npos);
  EXPECT_NE(r->body.find("<a href='/run/15'>15</a>"), std::string::npos) << "the runs it touches";
  const auto bad = client.Get("/signatures?since=2026-11-20&until=2026-11-10");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400);

  ASSERT_TRUE(test_support::chromium_installed())
      << "chromium is not installed (tools/setup.sh installs it)";
  const std::string url = "http://127.0.0.1:" + std::to_string(web.port()) + "/signatures";
  const test_support::RenderedPage shown =
      test_support::render_in_chromium(url, dir_->file("chromium.log"));
  ASSERT_EQ(shown.code, 0);
  EXPECT_NE(shown.dom.find("id=\"signatures\""), std::string::npos);
  for (const std::string& line : shown.console) ADD_FAILURE() << "console: " << line;
  const std::string shot = std::string(IMUCAL_BIN_DIR) + "/../tests/stationweb-signatures.png";
  EXPECT_EQ(test_support::chromium_screenshot(url, shot, 1200, 1000), 0);
}
