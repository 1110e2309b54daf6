// Issue #49 item 4, "one report": the same run diagnosed by `imucal diagnose ARCHIVE` (the field
// engineer's tool, on the archive the station stored) and by `stationctl diagnose RUN_ID` (through
// the daemon) prints the same report — the candidate effects in labelled columns and in the
// diagnosis' rank order, not a shorter table without headers. stationsim, stationd, stationctl and
// imucal run as real processes; the run carries an accelerometer K2 the station is not told about
// (the issue's K2-on-`short` case: the report must show K2 and the asymmetry it cannot be told
// apart from).
#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>
#include <string>
#include <vector>

#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

/// The candidate table of a diagnosis text: its header line (the one whose first column is
/// labelled "effect" and which labels a "score") and the rows after it up to the first blank line.
/// Empty when the text has no such header.
std::vector<std::string> one_report_candidate_table(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> table;
  for (std::string line; std::getline(in, line);) {
    if (table.empty()) {
      std::istringstream words(line);
      std::string first, second;
      words >> first >> second;
      if (first == "effect" && second == "score") table.push_back(line);
      continue;
    }
    if (line.find_first_not_of(' ') == std::string::npos) break;
    table.push_back(line);
  }
  return table;
}

/// The text without its first line (the run it names: an archive directory for imucal, the run id
/// for stationctl).
std::string one_report_body(const std::string& text) {
  const std::size_t eol = text.find('\n');
  return eol == std::string::npos ? "" : text.substr(eol + 1);
}

std::vector<std::string> one_report_words(const std::string& line) {
  std::istringstream in(line);
  std::vector<std::string> w;
  for (std::string s; in >> s;) w.push_back(s);
  return w;
}

TEST(StationOneReport, StationctlAndImucalPrintTheSameRankedCandidateTableWithHeaders) {
  Station st;
  SimOptions o;
  // 3x the catalogue's typical K2 (as tests/tools/imucal_diagnose_cli_test.cpp), per axis, SI.
  o.extra = {"--effect", "accel_quadratic_k2=6.118e-6,-4.589e-6,7.648e-6"};
  ASSERT_TRUE(st.start(o));
  const CmdResult run = st.ctl({"run", "start", "--serial", "ONE-0001", "--sequence", "short",
                                "--operator", "e2e", "--wait"},
                               180s);
  ASSERT_NE(run.exit_code, -1) << run.describe() << "\ndaemon log:\n" << st.daemon_log();
  const long long run_id = run_id_of(newest_run(st, "ONE-0001"));
  ASSERT_GT(run_id, 0) << run.describe();

  const CmdResult as_json = st.ctl({"diagnose", std::to_string(run_id), "--json"}, 300s);
  ASSERT_TRUE(as_json.exit_code == 0 || as_json.exit_code == 3) << as_json.describe();
  const json d = as_json.json_out();
  ASSERT_TRUE(d["archive"].is_string()) << d.dump(2).substr(0, 2000);
  const CmdResult station = st.ctl({"diagnose", std::to_string(run_id)}, 300s);
  const CmdResult field = run_command({bin("imucal"), "diagnose", d["archive"].get<std::string>()},
                                      st.dir().path(), 300s);
  // The same exit code for the same verdict (0 explained or consistent, 3 unexplained).
  EXPECT_EQ(station.exit_code, as_json.exit_code) << station.describe();
  EXPECT_EQ(field.exit_code, as_json.exit_code) << field.describe();

  const std::vector<std::string> from_station = one_report_candidate_table(station.out);
  const std::vector<std::string> from_imucal = one_report_candidate_table(field.out);
  ASSERT_FALSE(from_imucal.empty()) << field.describe();
  ASSERT_FALSE(from_station.empty()) << "stationctl diagnose: no labelled candidate table\n"
                                     << station.describe();
  EXPECT_EQ(from_station, from_imucal) << station.describe() << "\n" << field.describe();

  // Every column labelled, one row per candidate, in the diagnosis' rank order (the JSON's), the
  // score column holding each candidate's score.
  const std::vector<std::string> header = one_report_words(from_station[0]);
  for (const char* label : {"effect", "score", "LR", "p", "magnitude", "held-out", "note"})
    EXPECT_NE(std::find(header.begin(), header.end(), label), header.end())
        << label << " in: " << from_station[0];
  ASSERT_TRUE(d["candidates"].is_array());
  ASSERT_EQ(from_station.size(), d["candidates"].size() + 1) << station.out;
  for (std::size_t i = 0; i < d["candidates"].size(); ++i) {
    const json& c = d["candidates"][i];
    const std::vector<std::string> row = one_report_words(from_station[i + 1]);
    ASSERT_GE(row.size(), 2u) << from_station[i + 1];
    EXPECT_EQ(row[0], c["effect"].get<std::string>()) << "rank " << i + 1;
    if (c["score"].is_number()) {
      EXPECT_NEAR(std::stod(row[1]), c["score"].get<double>(), 0.051) << from_station[i + 1];
    }
  }
  // Not only the table: the whole report is the same, below the line naming the run.
  EXPECT_EQ(one_report_body(station.out), one_report_body(field.out));
  EXPECT_NE(station.out.find("run " + std::to_string(run_id)), std::string::npos) << station.out;
}

}  // namespace
}  // namespace imucal::e2e
