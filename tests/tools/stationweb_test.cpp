// build/bin/stationweb as QA uses it: a history written through the repository (several serials,
// stations, days and verdicts, live runs, a table run of two units, a gap diagnosis, capture
// counters, parameters one method cannot observe), the real server started on a free loopback
// port, every page fetched over HTTP. The numbers on the pages — read from the element ids and data
// attributes the pages carry for this — must equal what the repository returns (or, for the fleet
// pages, what the test computes from the rows it wrote); statuses are 200, 404 with a message, 400
// naming the field, 405 for anything but GET; a value with quotes and semicolons goes through
// every filter and the database stays as it was. Headless Chromium renders the unit and a fleet
// page: the expected elements in its DOM, no console message, and a screenshot of plausible size
// (build/tests/stationweb-*.png).
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <regex>
#include <sstream>

#include "db/history/fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/control/record_json.hpp"
#include "tests/db/fleet_history.hpp"
#include "tests/support/html_tags.hpp"
#include "tests/support/run_command.hpp"
#include "tests/tools/stationweb_process.hpp"
#include "tools/report/html_escape.hpp"
#include "tools/stationweb/httplib.hpp"

namespace imucal {
namespace {

namespace fs = std::filesystem;
using db::test::FleetRow;
using test_support::Attrs;
using test_support::number;
using test_support::section;
using test_support::tags;

// ----- the history and the server
// --------------------------------------------------------------------

/// Runs beyond tests/db/fleet_history.hpp's, for the run page's sections.
struct Extra {
  db::history::RunId table_first = 0, table_second = 0, diagnosed = 0, unobservable = 0;
};

/// Finishes `id` with `c` and adds it to `rows` as the fleet tests count it.
void finish(db::history::SqliteRepository& repo, db::history::RunId id,
            const db::history::RunCompletion& c, std::vector<FleetRow>& rows) {
  repo.finish_run(id, c);
  const db::history::RunRecord r = repo.show(id).run;
  FleetRow row{id, r.station, r.serial, r.started_at_ms, db::history::to_string(*r.verdict),
               {}, {},        {}};
  row.ains = c.calibrations.at(0).params.to_vector();
  row.ains_sigma = c.calibrations.at(0).sigma.to_vector();
  row.unobservable = c.calibrations.at(0).unobservable;
  rows.push_back(row);
}

/// `c` with plausible AINS values (tests/db/fleet_history.hpp) for `serial_level`.
db::history::RunCompletion plausible(db::history::RunCompletion c, int serial_level,
                                     std::size_t station) {
  static std::mt19937 rng(7);
  const auto unobservable = c.calibrations[0].unobservable;
  c.calibrations[0] = db::test::fleet_ains(rng, serial_level, station);
  c.calibrations[0].unobservable = unobservable;
  return c;
}

Extra write_extra_runs(db::history::SqliteRepository& repo, std::vector<FleetRow>& rows) {
  Extra e;
  const db::history::TimestampMs t = db::history::parse_time_utc("2024-03-03T08:00:00Z");
  db::history::NewRun first = db::test::new_run("SN-T1", t);
  first.station = "st-A";
  first.slot = "A";
  e.table_first = repo.create_run(first);
  db::history::NewRun second = db::test::new_run("SN-T2", t);
  second.station = "st-A";
  second.slot = "B";
  second.table_run_id = e.table_first;
  e.table_second = repo.create_run(second);
  finish(repo, e.table_first, plausible(db::test::pass_completion(101, t + 3000000), 1, 0), rows);
  finish(repo, e.table_second, plausible(db::test::review_completion(102, t + 3000000), 2, 0),
         rows);

  db::history::NewRun gap = db::test::new_run("SN-DIAG", t + 7200000);
  gap.station = "st-B";
  e.diagnosed = repo.create_run(gap);
  db::history::RunCompletion c = db::test::pass_completion(103, t + 9000000);
  c.state = db::history::RunState::kReview;
  c.reasons = {{"gap", "sim-to-real gap: explained by gyro_g_sensitivity"}};
  c.capture_json = R"({"complete": true, "frames_received": 912345, "samples_lost": 2})";
  c.diagnosis_json =
      R"({"verdict": "explained", "summary": "gyro g-sensitivity explains the gap", "best":)"
      R"( {"effect": "gyro_g_sensitivity", "magnitude": 0.04, "sigma": 0.004, "unit": "deg/h/g"},)"
      R"( "overall": {"gap": 3.2, "expected": 1, "sigma": 0.1, "p_value": 1e-9}})";
  finish(repo, e.diagnosed, plausible(c, 3, 1), rows);

  db::history::NewRun field = db::test::new_run("SN-DIAG", t + 14400000);
  field.station = "st-B";
  e.unobservable = repo.create_run(field);
  db::history::RunCompletion u = db::test::review_completion(104, t + 16000000);
  const std::vector<std::string> varsigma = {
      "table_misalignment_rad[0]", "table_misalignment_rad[1]", "table_misalignment_rad[2]"};
  u.calibrations[0].unobservable = varsigma;
  u.crosscheck->not_compared = varsigma;
  finish(repo, e.unobservable, plausible(u, 3, 1), rows);
  return e;
}

class StationwebTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<db::test::TempDir>();
    db_ = dir_->file("history.sqlite");
    {
      db::history::SqliteRepository repo(db_);
      rows_ = db::test::write_fleet_history(repo);
      extra_ = write_extra_runs(repo, rows_);
    }
    try {
      web_ = std::make_unique<test_support::StationwebProcess>(
          std::string(IMUCAL_BIN_DIR) + "/stationweb", db_, dir_->file("stationweb.log"),
          std::vector<std::string>{"--log-level", "debug"});
    } catch (const std::exception& e) {
      start_error_ = e.what();
    }
  }
  static void TearDownTestSuite() {
    web_.reset();
    dir_.reset();
  }
  void SetUp() override { ASSERT_TRUE(web_) << "stationweb did not start: " << start_error_; }

  static httplib::Client client() {
    httplib::Client c("127.0.0.1", web_->port());
    c.set_url_encode(false);  // the targets below are encoded as a browser would
    c.set_read_timeout(30, 0);
    return c;
  }
  /// GET `target`; the body, with the status in `status`.
  static std::string get(const std::string& target, int& status) {
    auto c = client();
    const auto r = c.Get(target.c_str());
    status = r ? r->status : -1;
    return r ? r->body : std::string();
  }
  static std::string get_ok(const std::string& target) {
    int status = 0;
    std::string body = get(target, status);
    EXPECT_EQ(status, 200) << target << "\n" << body.substr(0, 2000);
    return body;
  }
  static db::history::SqliteRepository repo() {
    return db::history::SqliteRepository(db_, {true, false, 5000});
  }

  static inline std::unique_ptr<db::test::TempDir> dir_;
  static inline std::string db_, start_error_;
  static inline std::vector<FleetRow> rows_;
  static inline Extra extra_;
  static inline std::unique_ptr<test_support::StationwebProcess> web_;
};

// ----- index and unit pages
// --------------------------------------------------------------------------

TEST_F(StationwebTest, IndexListsTheNewestRunsOfTheRepository) {
  const std::string html = get_ok("/?limit=30");
  auto r = repo();
  const auto total = tags(html, "<span id='total-runs'");
  ASSERT_EQ(total.size(), 1u);
  EXPECT_EQ(total[0]["data-value"], std::to_string(r.total_run_count()));
  const auto rows = tags(section(html, "recent-runs", "</table>"), "<tr class='run'");
  const auto newest = r.recent_runs(30);
  ASSERT_EQ(rows.size(), newest.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i]["data-run-id"], std::to_string(newest[i].run_id));
    EXPECT_EQ(rows[i]["data-serial"], newest[i].serial);
    EXPECT_EQ(rows[i]["data-station"], newest[i].station);
    EXPECT_EQ(rows[i]["data-verdict"],
              newest[i].verdict ? db::history::to_string(*newest[i].verdict) : "");
    EXPECT_NE(html.find("href='/run/" + std::to_string(newest[i].run_id) + "'"), std::string::npos);
    EXPECT_NE(html.find("href='/unit/" + newest[i].serial + "'"), std::string::npos);
  }
  EXPECT_NE(html.find("<form id='serial-search' action='/unit' method='get'>"), std::string::npos);
}

TEST_F(StationwebTest, UnitPageHistoryAndTrendEqualTheRepository) {
  for (const std::string serial : {"SN-3", "SN-DIAG"}) {
    SCOPED_TRACE(serial);
    const std::string html = get_ok("/unit/" + serial);
    auto r = repo();
    const auto history = r.history(serial);
    EXPECT_EQ(tags(html, "<span id='run-count'")[0]["data-value"], std::to_string(history.size()));
    const auto rows = tags(section(html, "history", "</table>"), "<tr class='run'");
    ASSERT_EQ(rows.size(), history.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
      EXPECT_EQ(rows[i]["data-run-id"], std::to_string(history[i].run_id));
      EXPECT_EQ(rows[i]["data-state"], db::history::to_string(history[i].state));
      EXPECT_EQ(rows[i]["data-started-ms"], std::to_string(history[i].started_at_ms));
    }
    std::string active;
    try {
      active = std::to_string(r.active_params(serial).run.run_id);
    } catch (const db::history::NotFound&) {
    }
    EXPECT_EQ(tags(html, "<p id='active-set'")[0]["data-run-id"], active);
    // Every drawn point is a stored AINS value with its sigma; every observable one is drawn.
    std::size_t expected_points = 0;
    std::map<std::pair<std::string, std::string>, std::pair<double, double>> stored;
    for (const auto& run : history)
      for (const auto& c : r.show(run.run_id).calibrations) {
        if (c.method != db::history::Method::kAins) continue;
        const auto v = c.params.to_vector(), s = c.sigma.to_vector();
        for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
          const std::string& name = calib::core::param_info(i).name;
          if (std::find(c.unobservable.begin(), c.unobservable.end(), name) != c.unobservable.end())
            continue;
          stored[{std::to_string(run.run_id), name}] = {v(i), s(i)};
          ++expected_points;
        }
      }
    const auto points = tags(html, "<circle class='pt");
    EXPECT_EQ(points.size(), expected_points);
    for (const Attrs& p : points) {
      const auto it = stored.find({p.at("data-run-id"), p.at("data-param")});
      ASSERT_NE(it, stored.end()) << p.at("data-run-id") << " " << p.at("data-param");
      EXPECT_EQ(number(p.at("data-value-si")), it->second.first);
      EXPECT_EQ(number(p.at("data-sigma-si")), it->second.second);
    }
    for (const char* group : {"accel_bias", "gyro_bias", "gyro_misalignment", "table_misalignment"})
      EXPECT_NE(html.find(std::string("<svg id='trend-") + group + "'"), std::string::npos);
  }
}

TEST_F(StationwebTest, TheSerialSearchRedirectsToTheUnitPage) {
  auto c = client();
  const auto r = c.Get("/unit?serial=SN-3");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 303);
  EXPECT_EQ(r->get_header_value("Location"), "/unit/SN-3");
}

// ----- the run page
// ----------------------------------------------------------------------------------

void expect_calibrations_equal(const std::string& html, const db::history::RunDetails& d) {
  const auto cells = tags(section(html, "calibrations", "</table>"), "<td class='num' data-method");
  std::size_t expected = 0;
  for (const auto& c : d.calibrations) {
    const auto v = c.params.to_vector(), s = c.sigma.to_vector();
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
      const std::string& name = calib::core::param_info(i).name;
      if (std::find(c.unobservable.begin(), c.unobservable.end(), name) != c.unobservable.end())
        continue;
      ++expected;
      const std::string m = db::history::to_string(c.method);
      const auto it = std::find_if(cells.begin(), cells.end(), [&](const Attrs& a) {
        return a.at("data-method") == m && a.at("data-param") == name;
      });
      ASSERT_NE(it, cells.end()) << m << " " << name;
      EXPECT_EQ(number(it->at("data-value-si")), v(i)) << m << " " << name;
      EXPECT_EQ(number(it->at("data-sigma-si")), s(i)) << m << " " << name;
    }
  }
  EXPECT_EQ(cells.size(), expected);
}

void expect_crosscheck_equal(const std::string& html, const db::history::RunDetails& d) {
  const auto div = tags(html, "<div id='crosscheck'");
  ASSERT_EQ(div.size(), 1u);
  ASSERT_TRUE(d.crosscheck);
  EXPECT_EQ(div[0]["data-verdict"], db::history::to_string(d.crosscheck->verdict));
  EXPECT_EQ(number(div[0]["data-k-sigma"]), d.crosscheck->k_sigma);
  const auto rows = tags(section(html, "crosscheck-table", "</table>"), "<tr data-param");
  ASSERT_EQ(rows.size(), 27u);
  const auto a = d.calibrations[0], b = d.calibrations[1];
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const std::string& name = calib::core::param_info(i).name;
    Attrs row = rows[static_cast<std::size_t>(i)];
    EXPECT_EQ(row["data-param"], name);
    const auto& nc = d.crosscheck->not_compared;
    const bool failed = std::any_of(d.crosscheck->failures.begin(), d.crosscheck->failures.end(),
                                    [&](const auto& f) { return f.term == name; });
    // Issue #52 item 2: nothing is compared against a method that did not converge.
    const bool compared =
        a.converged && b.converged && std::find(nc.begin(), nc.end(), name) == nc.end();
    EXPECT_EQ(row["data-status"], !compared ? "not compared" : failed ? "REVIEW" : "PASS") << name;
    if (!compared) continue;
    const double sa = a.sigma.to_vector()(i), sb = b.sigma.to_vector()(i);
    EXPECT_EQ(number(row["data-diff-si"]), a.params.to_vector()(i) - b.params.to_vector()(i));
    EXPECT_EQ(number(row["data-sigma-si"]), std::sqrt(sa * sa + sb * sb));
  }
}

TEST_F(StationwebTest, RunPageShowsWhatStationctlShowShowsWithTheRepositorysNumbers) {
  auto r = repo();
  const db::history::RunId review = rows_[7].run_id;  // fleet_history: run 7 is REVIEW
  for (db::history::RunId id :
       {rows_[1].run_id, review, extra_.diagnosed, extra_.unobservable, extra_.table_second}) {
    SCOPED_TRACE("run " + std::to_string(id));
    const std::string html = get_ok("/run/" + std::to_string(id));
    const db::history::RunDetails d = r.show(id);
    Attrs head = tags(html, "<p id='run-head'")[0];
    EXPECT_EQ(head["data-run-id"], std::to_string(id));
    EXPECT_EQ(head["data-serial"], d.run.serial);
    EXPECT_EQ(head["data-state"], db::history::to_string(d.run.state));
    EXPECT_EQ(head["data-verdict"], d.run.verdict ? db::history::to_string(*d.run.verdict) : "");
    Attrs archive = tags(html, "<p id='archive'")[0];
    EXPECT_EQ(archive["data-path"], d.run.archive_path);
    EXPECT_EQ(archive["data-sha256"], d.run.archive_sha256);
    const auto reasons = tags(html, "<li data-source");
    ASSERT_EQ(reasons.size(), d.run.reasons.size());
    for (std::size_t k = 0; k < reasons.size(); ++k)
      EXPECT_EQ(reasons[k]["data-source"], d.run.reasons[k].source);
    expect_calibrations_equal(html, d);
    expect_crosscheck_equal(html, d);
    // The text of `stationctl show`, whole, at the end of the page.
    const std::string text = station::control::render_show_text(station::control::show_result(d));
    EXPECT_NE(html.find(tools::report::html_escape(text)), std::string::npos);
  }
}

TEST_F(StationwebTest, RunPageShowsTheCaptureTheDiagnosisAndTheTableRunsUnits) {
  const std::string html = get_ok("/run/" + std::to_string(extra_.diagnosed));
  std::map<std::string, std::string> capture;
  for (Attrs& a : tags(section(html, "capture", "</table>"), "<tr data-counter"))
    capture[a["data-counter"]] = a["data-value"];
  EXPECT_EQ(capture, (std::map<std::string, std::string>{{"frames_received", "912345"},
                                                         {"samples_lost", "2"}}));
  EXPECT_EQ(tags(html, "<div id='diagnosis'")[0]["data-verdict"], "explained");
  EXPECT_NE(section(html, "diagnosis", "</div>").find("gyro_g_sensitivity"), std::string::npos);
  EXPECT_NE(section(html, "diagnosis", "</div>").find("p_value"), std::string::npos);

  const auto members = [](const std::string& page) {
    std::vector<std::string> ids;
    for (Attrs& a : tags(section(page, "siblings", "</table>"), "<tr class='run'"))
      ids.push_back(a["data-run-id"]);
    return ids;
  };
  const std::vector<std::string> both = {std::to_string(extra_.table_first),
                                         std::to_string(extra_.table_second)};
  EXPECT_EQ(members(get_ok("/run/" + both[0])), both);
  EXPECT_EQ(members(get_ok("/run/" + both[1])), both);
  EXPECT_TRUE(members(get_ok("/run/" + std::to_string(rows_[1].run_id))).empty());
}

// ----- the fleet page
// --------------------------------------------------------------------------------

/// The fleet page's tables against the test's own answers from the rows it wrote.
void expect_fleet_equal(const std::string& html, const std::vector<FleetRow>& rows,
                        const db::history::FleetFilter& f, int param) {
  Attrs window = tags(html, "<p id='window'")[0];
  EXPECT_EQ(window["data-since-ms"], f.since_ms ? std::to_string(*f.since_ms) : "");
  EXPECT_EQ(window["data-until-ms"], f.until_ms ? std::to_string(*f.until_ms) : "");
  std::map<std::string, std::int64_t> per_day;
  // pass, review, failed, station fault, aborted, interrupted, live; and the units' own outcomes
  std::map<std::string, std::array<std::int64_t, 8>> verdicts;
  std::map<std::string, std::vector<double>> values;
  for (const FleetRow& r : rows) {
    if (!db::test::fleet_row_matches(r, f)) continue;
    ++per_day[r.station + " " + db::history::format_time_utc(r.started_at_ms).substr(0, 10)];
    auto& v = verdicts[r.station];
    const char* const order[] = {"PASS",          "REVIEW",  "FAILED",
                                 "STATION-FAULT", "ABORTED", "INTERRUPTED"};
    const auto k = static_cast<std::size_t>(std::find(order, order + 6, r.verdict) - order);
    ++v[k];  // 6: live
    if (k < 3) ++v[7];
    if (const auto v = db::test::fleet_value(r, param)) values[r.station].push_back(*v);
  }
  std::map<std::string, std::int64_t> page_days;
  for (Attrs& c : tags(section(html, "runs-per-day", "</table>"), "<td class='num' data-station"))
    if (c["data-runs"] != "0")
      page_days[c["data-station"] + " " + c["data-day"]] = std::stoll(c["data-runs"]);
  EXPECT_EQ(page_days, per_day);
  std::map<std::string, std::array<std::int64_t, 8>> page_verdicts;
  for (Attrs& v : tags(section(html, "verdicts", "</table>"), "<tr data-station"))
    page_verdicts[v["data-station"]] = {
        std::stoll(v["data-pass"]),    std::stoll(v["data-review"]),
        std::stoll(v["data-failed"]),  std::stoll(v["data-station-fault"]),
        std::stoll(v["data-aborted"]), std::stoll(v["data-interrupted"]),
        std::stoll(v["data-live"]),    std::stoll(v["data-unit-outcomes"])};
  EXPECT_EQ(page_verdicts, verdicts);
  const auto dist = tags(section(html, "distribution", "</table>"), "<tr data-station");
  ASSERT_EQ(dist.size(), values.size());
  for (Attrs d : dist) {
    const auto e = db::test::expected_summary(values[d["data-station"]]);
    const double tol = 1e-12 * std::max(std::abs(e.min), std::abs(e.max));
    EXPECT_EQ(std::stoll(d["data-count"]), e.n);
    EXPECT_NEAR(number(d["data-mean"]), e.mean, tol);
    EXPECT_NEAR(number(d["data-std"]), e.sd, tol);
    EXPECT_EQ(number(d["data-min"]), e.min);
    EXPECT_NEAR(number(d["data-q1"]), e.q1, tol);
    EXPECT_NEAR(number(d["data-median"]), e.median, tol);
    EXPECT_NEAR(number(d["data-q3"]), e.q3, tol);
    EXPECT_EQ(number(d["data-max"]), e.max);
  }
}

TEST_F(StationwebTest, FleetPageNumbersEqualTheRowsWritten) {
  const db::history::TimestampMs day = 86400000;
  db::history::FleetFilter window;  // until=2024-03-04 is the whole of that day
  window.since_ms = db::history::parse_time_utc("2024-03-02");
  window.until_ms = db::history::parse_time_utc("2024-03-05");
  expect_fleet_equal(
      get_ok("/fleet?since=2024-03-02&until=2024-03-04&param=gyro_bias_radps%5B2%5D"), rows_,
      window, 14);
  // ς y: results that do not determine it are left out of its distribution.
  expect_fleet_equal(
      get_ok("/fleet?since=2024-03-02&until=2024-03-04&param=table_misalignment_rad%5B1%5D"), rows_,
      window, 25);
  db::history::FleetFilter narrow = window;
  narrow.station = "st-B";
  narrow.serial = "SN-2";
  narrow.since_ms = db::history::parse_time_utc("2024-03-01T06:00Z");
  expect_fleet_equal(
      get_ok("/fleet?since=2024-03-01T06:00Z&until=2024-03-04&station=st-B&serial=SN-2"
             "&param=accel_M%5B0%5D%5B1%5D"),
      rows_, narrow, 4);
  // Without since/until: the 30 days up to the newest run's day (the extra runs are older).
  auto r = repo();
  db::history::FleetFilter recent;
  recent.until_ms = (db::history::utc_day(r.recent_runs(1)[0].started_at_ms) + 1) * day;
  recent.since_ms = *recent.until_ms - 30 * day;
  const std::string html = get_ok("/fleet?param=table_misalignment_rad%5B1%5D");
  Attrs w = tags(html, "<p id='window'")[0];
  EXPECT_EQ(w["data-until-ms"], std::to_string(*recent.until_ms));
  EXPECT_EQ(w["data-since-ms"], std::to_string(*recent.since_ms));
  for (const char* id : {"runs-chart", "verdict-chart", "distribution-chart"})
    EXPECT_NE(html.find(std::string("<svg id='") + id + "'"), std::string::npos) << id;
}

// ----- statuses
// -----------------------------------------------------------------------------------

TEST_F(StationwebTest, UnknownSerialOrRunIsA404WithAMessage) {
  int status = 0;
  std::string body = get("/unit/SN-NOBODY", status);
  EXPECT_EQ(status, 404);
  EXPECT_NE(body.find("No unit with serial number &quot;SN-NOBODY&quot;"), std::string::npos)
      << body;
  body = get("/run/987654", status);
  EXPECT_EQ(status, 404);
  EXPECT_NE(body.find("No run 987654 in this history."), std::string::npos) << body;
  EXPECT_EQ(tags(body, "<p id='error'")[0]["data-status"], "404");
  body = get("/no/such/page", status);
  EXPECT_EQ(status, 404);
  EXPECT_NE(body.find("No page at /no/such/page"), std::string::npos) << body;
}

TEST_F(StationwebTest, MalformedInputIsA400NamingTheField) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"/run/abc", "run id"},
      {"/run/0", "run id"},
      {"/run/-3", "run id"},
      {"/run/99999999999999999999999", "run id"},
      {"/unit/bad%20serial", "serial"},
      {"/unit/" + std::string(40, 'A'), "serial"},
      {"/unit?serial=", "serial"},
      {"/unit?serial=a/b", "serial"},
      {"/fleet?since=2024-13-01", "since"},
      {"/fleet?until=yesterday", "until"},
      {"/fleet?since=2024-03-05&until=2024-03-01", "until"},
      {"/fleet?param=gyro_bias", "param"},
      {"/fleet?param=gyro_M%5B3%5D%5B0%5D", "param"},
      {"/fleet?serial=..", "serial"},
      {"/fleet?station=a%0Ab", "station"},
      {"/fleet?since=2024-03-01&since=2024-03-02", "since"},
      {"/?limit=0", "limit"},
      {"/?limit=many", "limit"},
  };
  for (const auto& [target, field] : cases) {
    int status = 0;
    const std::string body = get(target, status);
    EXPECT_EQ(status, 400) << target;
    const auto error = tags(body, "<p id='error'");
    ASSERT_EQ(error.size(), 1u) << target << "\n" << body;
    EXPECT_EQ(error[0].at("data-field"), field) << target;
    EXPECT_NE(body.find(">" + field + ": "), std::string::npos) << target << "\n" << body;
  }
}

TEST_F(StationwebTest, OnlyGetAndHeadAreServed) {
  auto c = client();
  const std::vector<std::function<httplib::Result()>> refused = {
      [&] { return c.Post("/", "x", "text/plain"); },
      [&] { return c.Post("/fleet", "", "text/plain"); },
      [&] { return c.Put("/run/1", "x", "text/plain"); },
      [&] { return c.Delete("/unit/SN-1"); },
      [&] { return c.Patch("/", "x", "text/plain"); },
      [&] { return c.Options("/"); }};
  for (const auto& request : refused) {
    const httplib::Result r = request();
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 405);
    EXPECT_EQ(r->get_header_value("Allow"), "GET, HEAD");
    EXPECT_NE(r->body.find("read-only"), std::string::npos);
  }
  const auto head = c.Head("/unit/SN-1");
  ASSERT_TRUE(head);
  EXPECT_EQ(head->status, 200);
}

/// Row counts of every table, integrity_check and the main file's bytes, read directly.
std::string database_state(const std::string& path) {
  sqlite3* db = nullptr;
  sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr);
  std::string state;
  for (const char* sql : {"SELECT count(*) FROM units", "SELECT count(*) FROM runs",
                          "SELECT count(*) FROM calibrations", "SELECT count(*) FROM crosschecks",
                          "SELECT count(*) FROM sqlite_master", "PRAGMA integrity_check"}) {
    sqlite3_stmt* st = nullptr;
    sqlite3_prepare_v2(db, sql, -1, &st, nullptr);
    if (st && sqlite3_step(st) == SQLITE_ROW)
      state += std::string(sql) + " = " +
               reinterpret_cast<const char*>(sqlite3_column_text(st, 0)) + "\n";
    sqlite3_finalize(st);
  }
  sqlite3_close(db);
  std::ifstream f(path, std::ios::binary);
  std::stringstream bytes;
  bytes << f.rdbuf();
  return state + "bytes " + std::to_string(std::hash<std::string>{}(bytes.str()));
}

TEST_F(StationwebTest, QuotesAndSemicolonsGoThroughEveryFilterAndTheDatabaseStaysAsItWas) {
  const std::string before = database_state(db_);
  ASSERT_NE(before.find("PRAGMA integrity_check = ok"), std::string::npos) << before;
  const std::string evil = "x%27%3B%20DROP%20TABLE%20runs%3B%20--";  // x'; DROP TABLE runs; --
  const std::vector<std::pair<std::string, int>> cases = {
      {"/unit/" + evil, 400},          {"/unit?serial=" + evil, 400},
      {"/run/" + evil, 400},           {"/?limit=" + evil, 400},
      {"/fleet?station=" + evil, 404}, {"/fleet?serial=" + evil, 400},
      {"/fleet?param=" + evil, 400},   {"/fleet?since=" + evil, 400},
      {"/fleet?until=" + evil, 400},   {"/fleet?station=st-A%27%20OR%20%271%27%3D%271", 404},
  };
  for (const auto& [target, expected] : cases) {
    int status = 0;
    const std::string body = get(target, status);
    EXPECT_EQ(status, expected) << target << "\n" << body.substr(0, 1500);
  }
  // A station nobody has: "unknown station" (issue #52 item 8), no runs listed, the value echoed.
  int status = 0;
  const std::string none = get("/fleet?station=" + evil + "&param=gyro_bias_radps%5B0%5D", status);
  EXPECT_EQ(status, 404);
  EXPECT_NE(none.find("unknown station"), std::string::npos);
  EXPECT_TRUE(tags(none, "<tr data-station").empty());
  EXPECT_NE(none.find("x&#39;; DROP TABLE runs; --"), std::string::npos);  // echoed, escaped
  EXPECT_EQ(database_state(db_), before);
}

TEST_F(StationwebTest, StartsThatCannotServeAreRefusedWithAMessage) {
  const std::string bin = std::string(IMUCAL_BIN_DIR) + "/stationweb";
  const std::string text_file = dir_->file("notes.txt");
  std::ofstream(text_file) << "not a database, only some text long enough for a header.\n";
  struct Case {
    std::string args;
    int code;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"", 2, "--db is required"},
      {"--db " + dir_->file("missing.sqlite"), 1, "missing.sqlite: no such database file"},
      {"--db " + text_file, 1, "notes.txt"},
      {"--db " + db_ + " --listen nohost", 2, "expected HOST:PORT"},
      {"--db " + db_ + " --listen 127.0.0.1:70000", 2, "port must be 0..65535"},
      {"--db " + db_ + " --listen 127.0.0.1:" + std::to_string(web_->port()), 1,
       "cannot listen on 127.0.0.1:" + std::to_string(web_->port())},
      {"--db postgresql://qa:secret@127.0.0.1:1/history", 1, "cannot connect"},
      {"--db postgresql://qa:secret@127.0.0.1:notaport/history", 1, "not a number"},
  };
  for (const Case& c : cases) {
    const auto r = test_support::run_command("timeout 20 " + bin + " " + c.args + " 2>&1");
    EXPECT_EQ(r.code, c.code) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.says), std::string::npos) << c.args << "\n" << r.out;
    EXPECT_EQ(r.out.find("secret"), std::string::npos) << "a password in the output: " << r.out;
  }
}

// ----- in a browser ----------------------------------------------------------------------------

const char* const kChromium =
    "timeout 120 chromium --headless --no-sandbox --disable-gpu --hide-scrollbars "
    "--enable-logging=stderr --v=0 ";

/// Chromium's console lines (page messages and uncaught errors) while loading `url`; the DOM.
std::string console_of(const std::string& url, const std::string& log, std::string& dom) {
  const auto r =
      test_support::run_command(kChromium + std::string("--dump-dom '") + url + "' 2>" + log);
  EXPECT_EQ(r.code, 0) << url;
  dom = r.out;
  std::ifstream f(log);
  std::string console;
  for (std::string line; std::getline(f, line);)
    if (line.find(":CONSOLE") != std::string::npos || line.find("Uncaught") != std::string::npos)
      console += line + "\n";
  return console;
}

std::pair<int, int> png_size_stationweb(const std::string& png) {
  if (png.size() < 24 || png.compare(1, 3, "PNG") != 0) return {0, 0};
  auto be = [&](std::size_t o) {
    return (static_cast<unsigned char>(png[o]) << 24) |
           (static_cast<unsigned char>(png[o + 1]) << 16) |
           (static_cast<unsigned char>(png[o + 2]) << 8) | static_cast<unsigned char>(png[o + 3]);
  };
  return {static_cast<int>(be(16)), static_cast<int>(be(20))};
}

TEST_F(StationwebTest, ChromiumRendersTheUnitAndFleetPagesWithoutConsoleMessages) {
  ASSERT_EQ(test_support::run_command("command -v chromium >/dev/null").code, 0)
      << "chromium is not installed: the browser check cannot run (tools/setup.sh installs it)";
  const std::string base = "http://127.0.0.1:" + std::to_string(web_->port());
  const std::string shots = std::string(IMUCAL_BIN_DIR) + "/../tests";
  struct Page {
    std::string name, target;
    std::vector<std::string> ids;
  };
  const std::vector<Page> pages = {
      {"unit",
       "/unit/SN-3",
       {"trend-accel_bias", "trend-gyro_bias", "trend-table_misalignment", "history"}},
      {"fleet",
       "/fleet?since=2024-03-01&until=2024-03-05&param=gyro_bias_radps%5B2%5D",
       {"runs-chart", "verdict-chart", "distribution-chart", "verdicts", "distribution",
        "runs-per-day"}}};
  for (const Page& p : pages) {
    SCOPED_TRACE(p.name);
    std::string dom;
    const std::string console = console_of(base + p.target, dir_->file(p.name + ".log"), dom);
    EXPECT_EQ(console, "") << "console messages on " << p.target;
    for (const std::string& id : p.ids)
      EXPECT_NE(dom.find("id=\"" + id + "\""), std::string::npos) << id;
    if (p.name == "unit") {
      EXPECT_NE(dom.find("<circle class=\"pt"), std::string::npos);
    }
    const std::string shot = shots + "/stationweb-" + p.name + ".png";
    fs::remove(shot);
    const auto r = test_support::run_command(std::string(kChromium) +
                                             "--window-size=1200,1600 --screenshot=" + shot + " '" +
                                             base + p.target + "' 2>/dev/null");
    ASSERT_EQ(r.code, 0);
    std::ifstream f(shot, std::ios::binary);
    std::stringstream png;
    png << f.rdbuf();
    EXPECT_EQ(png_size_stationweb(png.str()), (std::pair<int, int>{1200, 1600})) << shot;
    // A blank page compresses to a few kB; the rendered tables and pictures are far larger.
    EXPECT_GT(png.str().size(), 60000u) << shot;
  }
}

TEST_F(StationwebTest, TheConsoleCheckSeesAnErrorWhenThereIsOne) {
  ASSERT_EQ(test_support::run_command("command -v chromium >/dev/null").code, 0)
      << "chromium is not installed: the browser check cannot run (tools/setup.sh installs it)";
  const std::string page = dir_->file("broken.html");
  std::ofstream(page)
      << "<!DOCTYPE html><html><body><script>undefined_function();</script></body></html>";
  std::string dom;
  const std::string console = console_of("file://" + page, dir_->file("broken.log"), dom);
  EXPECT_NE(console.find("undefined_function"), std::string::npos) << console;
}

}  // namespace
}  // namespace imucal
