// Issue #52 on a real station's history (tests/data/qa_station_history: 24 runs made by stationsim,
// stationd and stationctl, each run's truth in its README), the audit's findings F5, F7, F8, F9,
// F12 and F13: the station signatures take one result per capture — the original's, or where the
// daemon interrupted the original, the first complete reprocess's — and only runs of the sequence
// the responses are measured on; /signatures, its trend, /fleet, /run and /unit?serial= refuse
// parameters they do not take, and the pages of figures answer data (CSV, JSON); a run the
// daemon's stop ended is nobody's abort but the daemon's; a download of a history that vanished
// under the server says so; a write is a 405 even without a body. Every expected figure is computed
// here from the file's rows (or read from its README's truth table), not from the code under test.
// (stationweb_lists_test.cpp and stationweb_pages_test.cpp hold the audit's other findings.)
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "db/history/sqlite_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"
#include "tests/support/html_tags.hpp"
#include "tests/tools/stationweb_process.hpp"
#include "tools/stationweb/httplib.hpp"

namespace imucal::stationweb_audit_test {

using db::history::RunId;

/// A copy of the committed history (SQLite writes its -shm beside a file it reads in WAL mode: the
/// source tree stays as it is).
std::string history_copy(const db::test::TempDir& dir) {
  const std::string path = dir.file("history.sqlite");
  if (!std::filesystem::exists(path))
    std::filesystem::copy_file(
        std::string(IMUCAL_SOURCE_DIR) + "/tests/data/qa_station_history/history.sqlite", path);
  return path;
}

/// A run of the file as the signature rule reads it.
struct Row {
  RunId id = 0;
  std::optional<RunId> origin;
  std::string sequence, serial;
  bool usable = false;  ///< factory, AINS with every term determined, the unit's own verdict,
                        ///< not calibrated from a partial archive
};

std::map<RunId, Row> read_rows(const std::string& path) {
  db::history::SqliteRepository repo(path, {true, false, 5000});
  std::map<RunId, Row> rows;
  for (const db::history::RunRecord& r : repo.recent_runs(0)) {
    Row row;
    row.id = r.run_id;
    row.origin = r.reprocessed_from;
    row.sequence = r.sequence_name;
    row.serial = r.serial;
    const db::history::RunDetails d = repo.show(r.run_id);
    bool partial = false;
    for (const auto& reason : d.run.reasons) partial |= reason.source == "partial archive";
    const bool unit_outcome = !r.verdict || *r.verdict == db::history::RunVerdict::kPass ||
                              *r.verdict == db::history::RunVerdict::kReview ||
                              *r.verdict == db::history::RunVerdict::kFailed;
    for (const auto& c : d.calibrations)
      if (c.method == db::history::Method::kAins && c.unobservable.empty())
        row.usable = r.setting == calib::core::Setting::kFactory && unit_outcome && !partial;
    rows[r.run_id] = row;
  }
  return rows;
}

/// The signature's runs by the rule: per capture (a run and the reprocesses reached from it), the
/// original if usable, else its first usable reprocess.
std::set<RunId> standing(const std::map<RunId, Row>& rows) {
  std::map<RunId, std::vector<RunId>>
      capture;  // root -> members, ascending (ids are creation order)
  for (const auto& [id, row] : rows) {
    RunId root = id;
    while (rows.at(root).origin) root = *rows.at(root).origin;
    capture[root].push_back(id);
  }
  std::set<RunId> out;
  for (const auto& [root, members] : capture)
    for (const RunId m : members)
      if (rows.at(m).usable) {
        out.insert(m);
        break;
      }
  return out;
}

TEST(SignatureCaptures, EachCaptureStandsOnceByItsOriginalOrItsFirstCompleteReprocess) {
  const db::test::TempDir dir;
  const std::string history = history_copy(dir);
  const auto rows = read_rows(history);
  const std::set<RunId> want = standing(rows);
  // The README's truth: {1, 12} is stood for by 1; {10, 11} by none (11 calibrated a partial
  // archive); {21, 22, 23} by 22 (21 was interrupted before its calibration).
  EXPECT_TRUE(want.count(1) && !want.count(12) && !want.count(10) && !want.count(11) &&
              want.count(22) && !want.count(23));
  db::history::SqliteFleetStats stats(history);
  std::set<RunId> got;
  for (const auto& r : stats.ains_results({})) got.insert(r.run_id);
  EXPECT_EQ(got, want);
}

class SignaturesPage : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = std::make_unique<db::test::TempDir>();
    web_ = std::make_unique<test_support::StationwebProcess>(
        std::string(IMUCAL_BIN_DIR) + "/stationweb", history_copy(*dir_),
        dir_->file("stationweb.log"));
  }
  static void TearDownTestSuite() {
    web_.reset();
    dir_.reset();
  }
  static httplib::Result get(const std::string& target) {
    httplib::Client c("127.0.0.1", web_->port());
    c.set_url_encode(false);
    c.set_read_timeout(60, 0);
    return c.Get(target.c_str());
  }
  static inline std::unique_ptr<db::test::TempDir> dir_;
  static inline std::unique_ptr<test_support::StationwebProcess> web_;
};

TEST_F(SignaturesPage, CountsOneResultPerCaptureOfTheMainSequenceAndSaysWhatItLeftOut) {
  const auto rows = read_rows(dir_->file("history.sqlite"));
  const std::set<RunId> all = standing(rows);
  std::map<std::string, int> per_sequence;
  for (const RunId id : all) ++per_sequence[rows.at(id).sequence];
  std::string main;
  for (const auto& [name, n] : per_sequence)
    if (main.empty() || n > per_sequence[main]) main = name;
  std::set<std::string> units;
  int runs = 0;
  for (const RunId id : all)
    if (rows.at(id).sequence == main) ++runs, units.insert(rows.at(id).serial);

  const auto page = get("/signatures?since=2026-11-01&until=2026-12-31");
  ASSERT_TRUE(page && page->status == 200);
  const auto station = test_support::tags(page->body, "<tr data-station=");
  ASSERT_EQ(station.size(), 1u);
  EXPECT_EQ(station[0]["data-runs"], std::to_string(runs));
  const auto json_reply = get("/signatures?since=2026-11-01&until=2026-12-31&format=json");
  ASSERT_TRUE(json_reply && json_reply->status == 200);
  EXPECT_NE(json_reply->get_header_value("Content-Type").find("application/json"),
            std::string::npos);
  const auto report = nlohmann::json::parse(json_reply->body);
  EXPECT_EQ(report["runs"].get<int>(), runs);
  EXPECT_EQ(report["sequence"], main);
  EXPECT_EQ(report["stations"][0]["units"].get<std::size_t>(), units.size());
  for (const auto& o : report["other_sequences"]) {
    const std::string name = o["sequence"].get<std::string>();
    EXPECT_EQ(o["runs"].get<int>(), per_sequence.at(name)) << name;
    EXPECT_NE(page->body.find(std::to_string(per_sequence.at(name)) + " runs of " + name),
              std::string::npos)
        << "the page says what it left out";
  }
  EXPECT_EQ(report["other_sequences"].size(), per_sequence.size() - 1);
  const auto csv = get("/signatures?since=2026-11-01&until=2026-12-31&format=csv");
  ASSERT_TRUE(csv && csv->status == 200);
  EXPECT_NE(csv->body.find("\nqa-station," + std::to_string(runs) + "," +
                           std::to_string(units.size()) + ","),
            std::string::npos)
      << csv->body;
}

TEST_F(SignaturesPage, UnknownParametersAreRefusedAndTheTrendAnswersData) {
  for (const std::string target :
       {"/signatures?Since=2026-11-01", "/signatures/trend?foo=1", "/signatures?format=xml"}) {
    const auto r = get(target);
    ASSERT_TRUE(r) << target;
    EXPECT_EQ(r->status, 400) << target;
    const auto e = test_support::tags(r->body, "<p id='error'");
    ASSERT_EQ(e.size(), 1u) << target;
  }
  const auto trend = get("/signatures/trend?period_days=30&format=json");
  ASSERT_TRUE(trend && trend->status == 200);
  const auto j = nlohmann::json::parse(trend->body);
  EXPECT_EQ(j["period_days"], 30);
  EXPECT_FALSE(j["periods"].empty());
  const auto empty = get("/signatures?since=2026-12-01");  // after the newest run's day
  ASSERT_TRUE(empty);
  EXPECT_EQ(empty->status, 400);
  EXPECT_EQ(empty->body.find("--since"), std::string::npos) << "a command-line flag on a web page";
}

TEST_F(SignaturesPage, AWriteIsRefusedAsOneEvenWithoutABody) {
  // As curl -X POST sends it: no Content-Length (httplib's client always sends one). The server
  // waits its read timeout (5 s) for a body before its parser gives up on the request.
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(web_->port()));
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(::connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
  const std::string request = "POST / HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n";
  ASSERT_EQ(::write(fd, request.data(), request.size()), static_cast<ssize_t>(request.size()));
  std::string reply;
  char buf[4096];
  for (ssize_t n; (n = ::read(fd, buf, sizeof buf)) > 0;) reply.append(buf, n);
  ::close(fd);
  EXPECT_EQ(reply.rfind("HTTP/1.1 405", 0), 0u) << reply.substr(0, 300);
  EXPECT_NE(reply.find("Allow: GET, HEAD"), std::string::npos) << reply.substr(0, 300);
}

// Last in this suite: the history vanishes under the running server.
TEST_F(SignaturesPage, ZZADownloadOfAHistoryThatVanishedSaysSo) {
  const auto before = get("/?format=csv");
  ASSERT_TRUE(before && before->status == 200);
  EXPECT_FALSE(before->has_header("X-History-Notice"));
  std::filesystem::remove(dir_->file("history.sqlite"));
  for (const std::string target :
       {"/?format=csv", "/?format=json", "/unit/SN-0001?format=json", "/signatures?format=json"}) {
    const auto r = get(target);
    ASSERT_TRUE(r) << target;
    EXPECT_NE(r->get_header_value("X-History-Notice"), "") << target;
  }
}

// ----- the pages of figures as data; parameters refused; a daemon's stop -------------------------

class AuditedDownloads : public SignaturesPage {};

TEST_F(AuditedDownloads, TheFleetsFiguresDownloadAsTheRowsGiveThem) {
  db::history::SqliteRepository repo(dir_->file("history.sqlite"), {true, false, 5000});
  const auto runs = repo.recent_runs(0);
  std::set<RunId> replaced;  // every run a later reprocess of its capture replaced
  for (const auto& r : runs)
    for (auto from = r.reprocessed_from; from; from = repo.show(*from).run.reprocessed_from)
      replaced.insert(*from);
  std::map<std::string, int> want;  // verdict -> factory captures
  for (const auto& r : runs)
    if (r.setting == calib::core::Setting::kFactory && !replaced.count(r.run_id) && r.verdict)
      ++want[db::history::to_string(*r.verdict)];
  const auto reply = get("/fleet?since=2026-11-01&until=2026-12-31&format=json");
  ASSERT_TRUE(reply && reply->status == 200);
  EXPECT_NE(reply->get_header_value("Content-Disposition").find("fleet.json"), std::string::npos);
  const auto j = nlohmann::json::parse(reply->body);
  ASSERT_EQ(j["verdicts"].size(), 1u);
  for (const char* v : {"PASS", "REVIEW", "FAILED", "STATION-FAULT", "ABORTED", "INTERRUPTED"})
    EXPECT_EQ(j["verdicts"][0][v].get<int>(), want[v]) << v;
  const auto csv =
      get("/fleet?since=2026-11-01&until=2026-12-31&format=csv&param=gyro_bias_radps%5B2%5D");
  ASSERT_TRUE(csv && csv->status == 200);
  EXPECT_NE(
      csv->body.find("\nqa-station," + std::to_string(want["PASS"]) + "," +
                     std::to_string(want["REVIEW"]) + "," + std::to_string(want["FAILED"]) + ","),
      std::string::npos)
      << csv->body;
  for (const std::string target : {"/fleet?Since=2026-11-01", "/unit?serial=SN-0001&foo=1",
                                   "/run/1?x=1", "/fleet?format=xml"}) {
    const auto r = get(target);
    ASSERT_TRUE(r) << target;
    EXPECT_EQ(r->status, 400) << target;
  }
}

TEST_F(AuditedDownloads, ARunDownloadsItsParametersAndTheDaemonsStopIsNoOperatorsAbort) {
  db::history::SqliteRepository repo(dir_->file("history.sqlite"), {true, false, 5000});
  const auto d = repo.show(4);
  const auto csv = get("/run/4?format=csv");
  ASSERT_TRUE(csv && csv->status == 200);
  std::size_t rows = 0;
  for (std::size_t p = csv->body.find("\n4,"); p != std::string::npos;
       p = csv->body.find("\n4,", p + 1))
    ++rows;
  EXPECT_EQ(rows, d.calibrations.size() * calib::core::ParamSet::kSize);
  const auto& ains = d.calibrations.at(0);
  char line[160];
  std::snprintf(line, sizeof line, "\n4,%s,gyro_bias_radps[2],%.17g,",
                db::history::to_string(ains.method), ains.params.to_vector()(14));
  EXPECT_NE(csv->body.find(line), std::string::npos) << line << "\n" << csv->body.substr(0, 400);
  // Run 13: stationd stopped by SIGTERM during the run (the README's truth), ABORTED.
  const auto stopped = get("/run/13?format=json");
  ASSERT_TRUE(stopped && stopped->status == 200);
  const auto j = nlohmann::json::parse(stopped->body);
  EXPECT_EQ(j["run"]["verdict"], "ABORTED");
  EXPECT_EQ(j["run"]["outcome_of"], "daemon");
  const auto page = get("/run/13");
  ASSERT_TRUE(page && page->status == 200);
  EXPECT_EQ(page->body.find("aborted by an operator"), std::string::npos);
  const auto operator_abort = get("/run/7?format=json");  // "unit loose in fixture"
  ASSERT_TRUE(operator_abort && operator_abort->status == 200);
  EXPECT_EQ(nlohmann::json::parse(operator_abort->body)["run"]["outcome_of"], "operator");
}

TEST_F(AuditedDownloads, ThePagesOfFiguresLinkTheirDownloads) {
  for (const std::string page : {"/fleet?param=gyro_bias_radps%5B2%5D", "/run/4", "/signatures"}) {
    const auto html = get(page);
    ASSERT_TRUE(html && html->status == 200) << page;
    const auto links = test_support::tags(html->body, "<a class=");
    int followed = 0;
    for (const auto& a : links) {
      const std::string kind = a["class"];
      if (kind != "csv" && kind != "json") continue;
      const auto r = get(a["href"]);
      ASSERT_TRUE(r) << a["href"];
      EXPECT_EQ(r->status, 200) << a["href"];
      EXPECT_NE(
          r->get_header_value("Content-Type").find(kind == "csv" ? "text/csv" : "application/json"),
          std::string::npos)
          << a["href"];
      ++followed;
    }
    EXPECT_EQ(followed, 2) << page;
  }
}

}  // namespace imucal::stationweb_audit_test
