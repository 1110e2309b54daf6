// Issue #52 items 1-5, 11 and 12 over a station's SQLite history: build/bin/stationweb started
// on tests/db/fleet_truth_history.hpp's history (field run, reprocesses, station fault, abort,
// interruption, a unit's FAILED, an unconverged NLSQ), its pages fetched over HTTP. The numbers
// on /fleet and /signatures are checked against the ones computed from the rows
// (tests/tools/fleet_truth_checks.hpp); the worst trend request must answer within a second with
// a bounded page and give its memory back; a history file deleted or replaced under the server
// is said on the page; `--db DIR` is refused naming the directory.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>

#include "calib/core/param_set.hpp"
#include "tests/db/fleet_truth_history.hpp"
#include "tests/support/headless_chromium.hpp"
#include "tests/support/html_tags.hpp"
#include "tests/support/run_command.hpp"
#include "tests/tools/fleet_truth_checks.hpp"
#include "tests/tools/stationweb_process.hpp"
#include "tools/stationweb/httplib.hpp"

namespace imucal {
namespace {

namespace fs = std::filesystem;
using db::test::TruthRow;
using test_support::Attrs;
using test_support::section;
using test_support::tags;

const std::string kBin = std::string(IMUCAL_BIN_DIR) + "/stationweb";

/// The running stationweb's port, for `rendered` (a free function beside the fixture).
struct StationwebTruthPort {
  static inline int port = 0;
};

class StationwebTruth : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<db::test::TempDir>();
    db_ = dir_->file("truth.sqlite");
    {
      db::history::SqliteRepository repo(db_);
      rows_ = db::test::write_truth_history(repo);
    }
    web_ =
        std::make_unique<test_support::StationwebProcess>(kBin, db_, dir_->file("stationweb.log"));
  }
  static void TearDownTestSuite() {
    web_.reset();
    dir_.reset();
  }
  static std::string get(const std::string& target, int* status = nullptr, int port = 0) {
    httplib::Client c("127.0.0.1", port ? port : web_->port());
    c.set_url_encode(false);
    c.set_read_timeout(10, 0);
    const auto r = c.Get(target.c_str());
    if (status) *status = r ? r->status : -1;
    if (!status) {
      EXPECT_TRUE(r && r->status == 200) << target << (r ? "\n" + r->body : "");
    }
    return r ? r->body : std::string();
  }

  static inline std::unique_ptr<db::test::TempDir> dir_;
  static inline std::string db_;
  static inline std::vector<TruthRow> rows_;
  static inline std::unique_ptr<test_support::StationwebProcess> web_;
};

// ----- item 1: what the statistics count ---------------------------------------------------------

TEST_F(StationwebTruth, FleetCountsFactoryRunsOnceEachCaptureAndStationFaultsApart) {
  test_support::expect_fleet_truth_under_every_filter(
      [](const std::string& target) { return get(target); }, rows_);
  const std::string p = "&param=gyro_bias_radps%5B2%5D";
  // The default distribution holds no field value: its minimum is a factory one.
  const auto dist =
      tags(section(get("/fleet?" + p), "distribution", "</table>"), "<tr data-station");
  for (Attrs d : dist) EXPECT_GT(test_support::number(d["data-min"]), -1e-6) << d["data-station"];
}

TEST_F(StationwebTruth, SettingAndVerdictFiltersRefuseUnknownValuesNamingTheField) {
  for (const auto& [target, field] : std::vector<std::pair<std::string, std::string>>{
           {"/fleet?setting=lab", "setting"}, {"/fleet?verdict=OK", "verdict"}}) {
    int status = 0;
    const std::string html = get(target, &status);
    EXPECT_EQ(status, 400) << target;
    EXPECT_NE(html.find("data-field='" + field + "'"), std::string::npos) << html;
  }
}

// Items 1-3 as QA's browser shows them: the pages rendered by headless Chromium (its DOM after
// load, no console message) carry the same numbers, computed from the rows, as the HTTP replies.
std::string rendered(const std::string& target, const std::string& log) {
  const test_support::RenderedPage page = test_support::render_in_chromium(
      "http://127.0.0.1:" + std::to_string(StationwebTruthPort::port) + target, log);
  EXPECT_EQ(page.code, 0) << target;
  EXPECT_TRUE(page.console.empty()) << target << ": " << page.console.front();
  return test_support::single_quoted(page.dom);
}

TEST_F(StationwebTruth, ChromiumShowsTheNumbersTheRowsGive) {
  ASSERT_TRUE(test_support::chromium_installed()) << "tools/setup.sh installs chromium";
  StationwebTruthPort::port = web_->port();
  const std::string log = dir_->file("chromium.log");
  test_support::expect_fleet_truth(rendered("/fleet?param=gyro_bias_radps%5B2%5D", log), rows_,
                                   "factory", "", 14);
  test_support::expect_fleet_truth(
      rendered("/fleet?setting=all&verdict=STATION-FAULT&param=gyro_bias_radps%5B2%5D", log), rows_,
      "", "STATION-FAULT", 14);
  test_support::expect_signatures_agree(rendered("/signatures", log), rendered("/fleet", log),
                                        rows_);
  const auto it =
      std::find_if(rows_.begin(), rows_.end(), [](const TruthRow& r) { return !r.nlsq_converged; });
  ASSERT_NE(it, rows_.end());
  const std::string run = rendered("/run/" + std::to_string(it->run_id), log);
  const auto rows = tags(section(run, "crosscheck-table", "</table>"), "<tr data-param");
  ASSERT_EQ(rows.size(), 27u);
  for (Attrs r : rows) EXPECT_EQ(r["data-status"], "not compared") << r["data-param"];
}

// ----- item 2: an unconverged method is not compared ---------------------------------------------

TEST_F(StationwebTruth, ACrossCheckAgainstAnUnconvergedMethodComparesNothing) {
  const auto it =
      std::find_if(rows_.begin(), rows_.end(), [](const TruthRow& r) { return !r.nlsq_converged; });
  ASSERT_NE(it, rows_.end());
  const std::string html = get("/run/" + std::to_string(it->run_id));
  const auto rows = tags(section(html, "crosscheck-table", "</table>"), "<tr data-param");
  ASSERT_EQ(rows.size(), 27u);
  for (Attrs r : rows) EXPECT_EQ(r["data-status"], "not compared") << r["data-param"];
  EXPECT_NE(html.find("id='not-converged'"), std::string::npos);
  EXPECT_EQ(section(html, "crosscheck-table", "</table>").find("class='PASS'>PASS"),
            std::string::npos);
}

// ----- item 3: /fleet and /signatures say the same
// ------------------------------------------------

TEST_F(StationwebTruth, FleetBannerAndSignaturesSayTheSameOfEveryStationAndCountItsUnits) {
  test_support::expect_signatures_agree(get("/signatures"), get("/fleet"), rows_);
}

// ----- item 4: dates beyond the served range
// ------------------------------------------------------

TEST_F(StationwebTruth, AbsurdDatesAreClampedWithAMessageAndPrintedWell) {
  for (const std::string target :
       {"/fleet?until=9999-12-31", "/fleet?since=0001-01-01&until=9999-12-31",
        "/signatures?since=0001-01-01&until=9999-12-31"}) {
    SCOPED_TRACE(target);
    const std::string html = get(target);
    const std::string window = section(html, "window", "</p>");
    EXPECT_EQ(window.find("10000"), std::string::npos) << window;
    EXPECT_TRUE(std::regex_search(window, std::regex("\\d{4}-\\d\\d-\\d\\d \\d\\d:\\d\\d:\\d\\d")))
        << window;
    EXPECT_NE(html.find("id='window-note'"), std::string::npos);
    EXPECT_NE(html.find("2999-12-31 is used"), std::string::npos);
  }
}

// ----- item 5: the worst request
// ------------------------------------------------------------------

long rss_kib(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

TEST_F(StationwebTruth, TheWorstTrendRequestIsBoundedFastAndGivesItsMemoryBack) {
  get("/signatures");  // the responses are measured once per process: not this request's cost
  const long before = rss_kib(web_->pid());
  ASSERT_GT(before, 0);
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  const std::string html =
      get("/signatures/trend?since=0001-01-01&until=9999-12-31&period_days=1", &status);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(status, 200) << html.substr(0, 3000);
  EXPECT_LT(s, 1.0) << "the worst request took " << s << " s";
  EXPECT_LT(html.size(), 4u << 20) << "a bounded page";
  const Attrs window = tags(html, "<p id='window'")[0];
  EXPECT_LE(std::stol(window.at("data-periods")), 366);
  EXPECT_NE(html.find("At most 366 periods"), std::string::npos);
  const long after = rss_kib(web_->pid());
  EXPECT_LT(after - before, 64 * 1024) << "RSS " << before << " kB before, " << after << " after";
  // A year of daily periods: at most about two dozen axis labels, each with its year.
  const std::string svg = section(html, "signature-trend", "</svg>");
  const std::regex label(">\\d{4}-\\d\\d-\\d\\d</text>");
  const auto labels =
      std::distance(std::sregex_iterator(svg.begin(), svg.end(), label), std::sregex_iterator());
  EXPECT_GT(labels, 0);
  EXPECT_LE(labels, 26);
}

// ----- item 12: labels and numbers
// ----------------------------------------------------------------

TEST_F(StationwebTruth, TrendPeriodsStartAtSinceWithTheYear) {
  const std::string html = get("/signatures/trend?since=2026-11-16&period_days=7");
  const std::string table = section(html, "trend", "</table>");
  const auto first = table.find("<th class='num'>");
  ASSERT_NE(first, std::string::npos) << html.substr(0, 3000);
  EXPECT_EQ(table.substr(first + 16, 10), "2026-11-16") << table.substr(0, 400);
}

/// Decimal places showing a σ's second significant digit (the test's own rule).
int decimals(double sigma) {
  return std::clamp(1 - static_cast<int>(std::floor(std::log10(sigma))), 0, 12);
}

TEST_F(StationwebTruth, NumbersHaveThePrecisionTheirSigmaAllowsAndLabelsTheirUnits) {
  const auto converged = std::find_if(rows_.begin(), rows_.end(), [](const TruthRow& r) {
    return r.nlsq_converged && r.ains && r.setting == "factory";
  });
  const std::string html = get("/run/" + std::to_string(converged->run_id));
  const std::string table = section(html, "crosscheck-table", "</table>");
  int checked = 0;
  for (std::size_t at = table.find("<tr data-param"); at != std::string::npos;
       at = table.find("<tr data-param", at + 1)) {
    const std::string row = table.substr(at, table.find("</tr>", at) - at);
    Attrs a = tags(row, "<tr data-param")[0];
    if (!a.count("data-sigma-si")) continue;
    const int i = db::history::param_index(a["data-param"]);
    const double k = calib::core::param_info(i).si_to_human;
    const double diff = test_support::number(a["data-diff-si"]) * k;
    const double sigma = test_support::number(a["data-sigma-si"]) * k;
    char expected[64];
    std::snprintf(expected, sizeof expected, "%.*f", decimals(sigma), diff);
    EXPECT_NE(row.find(std::string("<td class='num'>") + expected + "</td>"), std::string::npos)
        << a["data-param"] << ": " << expected << " in " << row;
    ++checked;
  }
  EXPECT_EQ(checked, 27);
  const std::string fleet = get("/fleet?param=gyro_bias_radps%5B2%5D");
  EXPECT_NE(section(fleet, "distribution", "</table>").find("<th class='num'>mean (deg/h)</th>"),
            std::string::npos);
  // st-B ran one unit on one day twice; a day with one run says "1 run".
  EXPECT_NE(fleet.find(": 1 run<"), std::string::npos);
  EXPECT_EQ(fleet.find(": 1 runs"), std::string::npos);
}

// ----- item 11: the history file under a running server
// -------------------------------------------

TEST_F(StationwebTruth, AHistoryDeletedOrReplacedUnderTheServerIsSaid) {
  const std::string copy = dir_->file("copy.sqlite");
  fs::copy_file(db_, copy);
  test_support::StationwebProcess web(kBin, copy, dir_->file("copy.log"));
  EXPECT_EQ(get("/", nullptr, web.port()).find("id='notice'"), std::string::npos);
  fs::rename(copy, copy + ".moved");
  fs::copy_file(db_, copy);  // another file at the same path
  const std::string replaced = get("/fleet", nullptr, web.port());
  EXPECT_NE(section(replaced, "notice", "</p>").find("was replaced"), std::string::npos);
  fs::remove(copy);
  int status = 0;
  const std::string gone = get("/run/1", &status, web.port());
  EXPECT_EQ(status, 200);
  EXPECT_NE(section(gone, "notice", "</p>").find("is gone"), std::string::npos) << gone;
}

TEST_F(StationwebTruth, ADirectoryAsTheHistoryIsRefusedNamingIt) {
  const std::string d = dir_->file("a-directory");
  fs::create_directory(d);
  const auto r = test_support::run_command(kBin + " --db " + d + " --listen 127.0.0.1:0 2>&1");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(d + ": is a directory"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("disk I/O error"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace imucal
