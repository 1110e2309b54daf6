// Station signatures period by period (issue #25): a station whose table drifts out of square
// between services. Four simulated weeks of 6 stations (4 units each and a golden-unit visit,
// every run through the station's pipeline, tools/fleetsim write_history), st-02's inner axis
// leaning 0, 3, 6 and 9″ towards the outer one in weeks 1-4. `stationctl --db F stations
// --signatures --trend` must show st-02 sound in week 1 and flagged with the non-orthogonality in
// weeks 2-4, its fitted size growing with the truth, no other station flagged in any week; exit 1
// (flagged in the newest week); stationweb's /signatures/trend the same, its picture rendered by
// headless Chromium without a console message.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "calib/core/conventions.hpp"
#include "tests/db/history_fixtures.hpp"
#include "tests/support/headless_chromium.hpp"
#include "tests/support/html_tags.hpp"
#include "tests/support/run_command.hpp"
#include "tests/tools/stationweb_process.hpp"
#include "tools/fleetsim/fleet_sim.hpp"
#include "tools/stationweb/httplib.hpp"

using namespace imucal;
using nlohmann::json;
using test_support::run_command;

namespace {

constexpr int kWeeks = 4;
constexpr std::size_t kDrifting = 2;
constexpr double kDriftArcsecPerWeek = 3.0;

class SignatureTrend : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new db::test::TempDir();
    db_ = dir_->file("four-weeks.sqlite");
    db::history::SqliteRepository repo(db_);
    const db::history::TimestampMs t0 = db::history::parse_time_utc("2026-11-02T00:00:00Z");
    for (int w = 0; w < kWeeks; ++w) {
      // Each week its own units (the seed names them), the same stations and golden unit.
      tools::fleetsim::FleetSpec spec = tools::fleetsim::sound_fleet(6, 20.0 * kArcsecToRad, 31);
      spec.seed = 310 + static_cast<std::uint64_t>(w);
      spec.units_per_station = 4;
      spec.stations[kDrifting].nonorthogonality_rad = kDriftArcsecPerWeek * w * kArcsecToRad;
      tools::fleetsim::write_history(spec, repo, t0 + w * 7 * 86400000LL + 3600000);
    }
  }
  static void TearDownTestSuite() { delete dir_; }

  static inline db::test::TempDir* dir_ = nullptr;
  static inline std::string db_;
};

}  // namespace

TEST_F(SignatureTrend, ADriftingTableIsFlaggedFromTheWeekItLeavesSquareAndNoOtherStation) {
  const std::string cmd = std::string(IMUCAL_BIN_DIR) + "/stationctl --db " + db_ +
                          " stations --signatures --trend --since 2026-11-02 --until 2026-11-29";
  const auto r = run_command(cmd + " --json 2>/dev/null");
  EXPECT_EQ(r.code, 1) << "flagged in the newest week: exit 1\n" << r.out;
  const json trend = json::parse(r.out);
  ASSERT_EQ(trend["periods"].size(), static_cast<std::size_t>(kWeeks)) << trend.dump(1);
  EXPECT_EQ(trend["stations"].size(), 6u);
  double last_size = 0;
  for (int w = 0; w < kWeeks; ++w) {
    const json& period = trend["periods"][static_cast<std::size_t>(w)];
    ASSERT_EQ(period["stations"].size(), 6u) << "week " << w;
    for (std::size_t s = 0; s < 6; ++s) {
      const json& cell = period["stations"][s];
      SCOPED_TRACE("week " + std::to_string(w + 1) + " " + cell["station"].get<std::string>());
      ASSERT_TRUE(cell["assessed"].get<bool>());
      const bool drifted = s == kDrifting && w > 0;
      ASSERT_EQ(cell["flagged"].get<bool>(), drifted) << cell.dump(1);
      if (!drifted) continue;
      EXPECT_EQ(cell["alarm"]["effect"], "table_nonorthogonality");
      const double size = cell["alarm"]["size"].get<double>();
      EXPECT_LT(std::abs(size - kDriftArcsecPerWeek * w), 4 * cell["alarm"]["sigma"].get<double>());
      EXPECT_GT(size, last_size) << "the fit grows with the drift";
      last_size = size;
    }
  }
  const auto text = run_command(cmd + " 2>&1");
  EXPECT_NE(text.out.find("st-02 flagged:\n    2026-11-09: table axis non-orthogonality +"),
            std::string::npos)
      << text.out;
}

TEST_F(SignatureTrend, TheWebPageDrawsTheSameFlags) {
  test_support::StationwebProcess web(std::string(IMUCAL_BIN_DIR) + "/stationweb", db_,
                                      dir_->file("stationweb.log"));
  httplib::Client client("127.0.0.1", web.port());
  client.set_read_timeout(60, 0);
  const auto r = client.Get("/signatures/trend?since=2026-11-02&until=2026-11-29");
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_NE(r->body.find("<svg id='signature-trend'"), std::string::npos);
  const auto flagged = test_support::tags(r->body, "<circle class='pt flagged'");
  ASSERT_EQ(flagged.size(), 3u) << "st-02 in weeks 2-4";
  for (const auto& point : flagged) EXPECT_EQ(point["data-station"], "st-02");
  EXPECT_NE(r->body.find("data-station='st-02' data-period='2026-11-09' data-flagged='1'"),
            std::string::npos);
  EXPECT_EQ(r->body.find("data-station='st-02' data-period='2026-11-02' data-flagged='1'"),
            std::string::npos);
  const auto bad = client.Get("/signatures/trend?period_days=0");
  ASSERT_TRUE(bad);
  EXPECT_EQ(bad->status, 400);
  EXPECT_NE(bad->body.find("period_days"), std::string::npos);

  ASSERT_TRUE(test_support::chromium_installed())
      << "chromium is not installed (tools/setup.sh installs it)";
  const std::string url = "http://127.0.0.1:" + std::to_string(web.port()) +
                          "/signatures/trend?since=2026-11-02&until=2026-11-29";
  const test_support::RenderedPage shown =
      test_support::render_in_chromium(url, dir_->file("chromium.log"));
  ASSERT_EQ(shown.code, 0);
  EXPECT_NE(shown.dom.find("id=\"signature-trend\""), std::string::npos);
  for (const std::string& line : shown.console) ADD_FAILURE() << "console: " << line;
  const std::string shot = std::string(IMUCAL_BIN_DIR) + "/../tests/stationweb-signature-trend.png";
  EXPECT_EQ(test_support::chromium_screenshot(url, shot, 1200, 900), 0);
}
