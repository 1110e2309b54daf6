// The export's row shapes (issue #50 item 4): the default CSV has a row per run and method — five
// PASS runs give ten rows — and `--per-run` (db/history/export_per_run.hpp) one row per run with
// each method's columns side by side, the same bytes as the default shape's fields; JSON per run
// gathers a run's calibrations into one object.
#include "db/history/export_per_run.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <sstream>

#include "db/history/export.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db {
using namespace imucal::db::history;
namespace {

using nlohmann::json;
using test::TempDir;

constexpr TimestampMs kT0PerRun = 1714560000000;  // 2024-05-01T10:40:00Z
/// A reason that needs every kind of CSV quoting.
const std::string kAwkwardReason = "table fault, code 7: \"e-stop\"\r\nafter step 3";

/// RFC 4180 records (CRLF-terminated; quoted fields may hold commas, quotes and line breaks).
std::vector<std::vector<std::string>> csv_records(const std::string& text) {
  std::vector<std::vector<std::string>> records(1);
  std::string field;
  bool quoted = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      records.back().push_back(std::move(field));
      field.clear();
    } else if (c == '\r' && i + 1 < text.size() && text[i + 1] == '\n') {
      records.back().push_back(std::move(field));
      field.clear();
      records.emplace_back();
      ++i;
    } else {
      field += c;
    }
  }
  EXPECT_TRUE(records.back().empty() && field.empty()) << "the last record does not end in CRLF";
  records.pop_back();
  return records;
}

std::size_t column(const std::vector<std::string>& header, const std::string& name) {
  const auto it = std::find(header.begin(), header.end(), name);
  EXPECT_NE(it, header.end()) << "no column " << name;
  return static_cast<std::size_t>(it - header.begin());
}

/// Five PASS runs (AINS + NLSQ each) and a failed run without results.
void five_pass_runs_and_a_failure(SqliteRepository& repo) {
  for (int i = 0; i < 5; ++i) {
    const RunId id = repo.create_run(test::new_run("SN-0001", kT0PerRun + i * 3600000));
    repo.finish_run(id, test::pass_completion(i, kT0PerRun + i * 3600000 + 60000));
  }
  const RunId failed = repo.create_run(test::new_run("SN-0002", kT0PerRun + 6 * 3600000));
  RunCompletion c;
  c.state = RunState::kFailed;
  c.ended_at_ms = kT0PerRun + 6 * 3600000 + 1000;
  c.reason = kAwkwardReason;
  repo.finish_run(failed, c);
}

TEST(ExportPerRun, CsvGivesOneRowPerRunWithBothMethodsColumnsAsTheDefaultShapeHasThem) {
  TempDir dir;
  SqliteRepository repo(dir.file("export.db"));
  five_pass_runs_and_a_failure(repo);
  std::ostringstream per_method, per_run;
  EXPECT_EQ(export_in_shape(repo, {}, "csv", false, per_method), 11u);  // 5 x 2 + 1
  EXPECT_EQ(export_in_shape(repo, {}, "csv", true, per_run), 6u);
  const auto m = csv_records(per_method.str()), r = csv_records(per_run.str());
  ASSERT_EQ(m.size(), 12u);
  ASSERT_EQ(r.size(), 7u);
  const std::vector<std::string>& mh = m[0];
  const std::vector<std::string>& rh = r[0];
  EXPECT_EQ(std::count(rh.begin(), rh.end(), "method"), 0) << "the method is in the prefixes";
  // Every per-method column but "method" once per method, the run's columns once.
  EXPECT_EQ(rh.size(),
            mh.size() - 1 +
                2 * (std::size(kCsvCalibrationColumns) - 1 + 2 * calib::core::ParamSet::kSize));
  for (std::size_t row = 1; row < r.size(); ++row) ASSERT_EQ(r[row].size(), rh.size()) << row;

  // Each per-method row's fields are found under its method's prefix in its run's row.
  const std::size_t m_run = column(mh, "run_id"), m_method = column(mh, "method");
  for (std::size_t row = 1; row < m.size(); ++row) {
    const auto& pm = m[row];
    const auto it = std::find_if(r.begin() + 1, r.end(), [&](const auto& x) {
      return x[column(rh, "run_id")] == pm[m_run];
    });
    ASSERT_NE(it, r.end()) << "run " << pm[m_run] << " has no per-run row";
    for (const std::string name : {"serial", "verdict", "failure_reason", "crosscheck_k_sigma"})
      EXPECT_EQ((*it)[column(rh, name)], pm[column(mh, name)]) << name;
    if (pm[m_method].empty()) continue;
    for (const std::string name : {"converged", "accel_bias_mps2[0]", "sigma.gyro_M[2][2]"})
      EXPECT_EQ((*it)[column(rh, pm[m_method] + "." + name)], pm[column(mh, name)])
          << pm[m_method] << "." << name << " of run " << pm[m_run];
  }
  // A PASS run: AINS and NLSQ filled, legacy empty; the failed run: no method's columns, its
  // reason intact through the quoting.
  EXPECT_FALSE(r[1][column(rh, "ains.accel_bias_mps2[0]")].empty());
  EXPECT_FALSE(r[1][column(rh, "nlsq.accel_bias_mps2[0]")].empty());
  EXPECT_TRUE(r[1][column(rh, "legacy.accel_bias_mps2[0]")].empty());
  const auto& failed = r.back();
  EXPECT_EQ(failed[column(rh, "serial")], "SN-0002");
  EXPECT_EQ(failed[column(rh, "failure_reason")], kAwkwardReason);
  EXPECT_TRUE(failed[column(rh, "ains.converged")].empty());
}

TEST(ExportPerRun, JsonAndNdjsonGiveOneObjectPerRunWithItsCalibrations) {
  TempDir dir;
  SqliteRepository repo(dir.file("export.db"));
  five_pass_runs_and_a_failure(repo);
  std::ostringstream array, lines;
  EXPECT_EQ(export_per_run(repo, {}, "json", array), 6u);
  EXPECT_EQ(export_per_run(repo, {}, "ndjson", lines), 6u);
  const json runs = json::parse(array.str());
  ASSERT_EQ(runs.size(), 6u);
  std::set<long long> ids;
  for (const json& run : runs) {
    ids.insert(run.at("run_id").get<long long>());
    const bool failed = run.at("state") == "failed";
    ASSERT_EQ(run.at("calibrations").size(), failed ? 0u : 2u) << run.dump();
    if (failed) continue;
    EXPECT_EQ(run["calibrations"][0].at("method"), "ains");
    EXPECT_EQ(run["calibrations"][1].at("method"), "nlsq");
    EXPECT_EQ(run.at("crosscheck").at("verdict"), "PASS");
  }
  EXPECT_EQ(ids.size(), 6u) << "a run split over two objects";
  std::istringstream in(lines.str());
  std::size_t n = 0;
  for (std::string line; std::getline(in, line); ++n) EXPECT_EQ(json::parse(line), runs[n]);
  EXPECT_EQ(n, 6u);
}

TEST(ExportPerRun, AnEmptySelectionIsAHeaderOrAnEmptyArrayAndAnUnknownFormatIsRefused) {
  TempDir dir;
  SqliteRepository repo(dir.file("export.db"));
  std::ostringstream csv, array, bad;
  EXPECT_EQ(export_per_run(repo, {}, "csv", csv), 0u);
  EXPECT_EQ(csv_records(csv.str()).size(), 1u);
  EXPECT_EQ(export_per_run(repo, {}, "json", array), 0u);
  EXPECT_EQ(json::parse(array.str()), json::array());
  EXPECT_THROW(export_per_run(repo, {}, "xml", bad), InvalidInput);
}

}  // namespace
}  // namespace imucal::db
